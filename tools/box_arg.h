// Parsing of a box given on the command line (`--box` of `relief preview` and
// `relief query`).
#pragma once

#include <string>

#include "relief/types.h"

namespace relief::cli {

// Accepts "xmin,ymin,xmax,ymax" (every height: z from -inf to +inf, as
// box_2d makes it) or "xmin,ymin,zmin,xmax,ymax,zmax". Every value must be a
// finite number and min <= max on each axis (a zero-width box is allowed: the
// box is closed, so it still selects the points on its faces). On failure
// returns false with `error` saying what is wrong; `out` is then untouched.
bool parse_box(const std::string& text, relief::Box3d& out, std::string& error);

}  // namespace relief::cli
