// apply_ingest_options: the one parser of ingest options by name (the CLI's
// flags and the Python bindings' keyword arguments).
#include <catch2/catch.hpp>

#include "relief/ingest.h"

using namespace relief;

namespace {

Status apply(IngestOptionSet set, std::vector<NamedOption> given, IngestOptions& o,
             OptionSpelling spelling = OptionSpelling::kPython) {
  return apply_ingest_options(set, given, spelling, o);
}

}  // namespace

TEST_CASE("ingest options: values by the CLI's names reach IngestOptions", "[ingest][options]") {
  IngestOptions o;
  REQUIRE(apply(IngestOptionSet::kCompress,
                {{"tolerance", "0.01"}, {"color_tolerance", "3"}, {"intensity-tolerance", "12"}, {"threads", "2"},
                 {"memory", "512M"},
                 {"chunk-edge", "8"}, {"cell", "0.25"}, {"codec", "jpeg2000"}, {"verify", "true"},
                 {"allow_sparse", ""}, {"columns", "x,y,z"}},
                o)
              .is_ok());
  CHECK(o.mode == IngestMode::kBounded);
  CHECK(o.tolerance == 0.01);
  CHECK(o.color_tolerance == 3);
  CHECK(o.intensity_tolerance == 12);
  CHECK(o.threads == 2);
  CHECK(o.memory_budget == (std::uint64_t{512} << 20));
  CHECK(o.chunk_edge == 8);
  CHECK(o.codec.cell_size == 0.25);
  CHECK(o.codec.image_codec == ImageCodec::kJpeg2000);
  CHECK(o.verify_blobs);
  CHECK(o.allow_sparse);
  CHECK_FALSE(o.assume_crs);
  CHECK(o.reader.xyz_columns == "x,y,z");

  IngestOptions r;
  REQUIRE(apply(IngestOptionSet::kCompress, {{"error-target", "0.02"}}, r).is_ok());
  CHECK(r.mode == IngestMode::kResample);
  CHECK(r.error_target == 0.02);

  // --keep-order: a new archive's property (compress and stream).
  IngestOptions k;
  CHECK_FALSE(k.keep_order);
  REQUIRE(apply(IngestOptionSet::kCompress, {{"keep_order", ""}}, k).is_ok());
  CHECK(k.keep_order);
  IngestOptions ks;
  REQUIRE(apply(IngestOptionSet::kStream, {{"keep-order", "true"}}, ks).is_ok());
  CHECK(ks.keep_order);
  // --fast-geometry: likewise (chunk format 13 for octree geometry).
  IngestOptions f;
  CHECK_FALSE(f.fast_geometry);
  REQUIRE(apply(IngestOptionSet::kCompress, {{"fast_geometry", ""}}, f).is_ok());
  CHECK(f.fast_geometry);
  IngestOptions fs;
  REQUIRE(apply(IngestOptionSet::kStream, {{"fast-geometry", "true"}}, fs).is_ok());
  CHECK(fs.fast_geometry);
}

TEST_CASE("ingest options: refused values name the option as the caller spells it", "[ingest][options]") {
  const auto refused = [](IngestOptionSet set, std::vector<NamedOption> given, OptionSpelling spelling) {
    IngestOptions o;
    const Status s = apply_ingest_options(set, given, spelling, o);
    CHECK(s.code() == StatusCode::kInvalidArgument);
    return s.message();
  };
  const auto py = OptionSpelling::kPython;
  const auto cli = OptionSpelling::kCli;
  CHECK(refused(IngestOptionSet::kCompress, {{"tolerance", "0"}}, py) == "tolerance must be a positive number");
  CHECK(refused(IngestOptionSet::kCompress, {{"tolerance", "nan"}}, cli) ==
        "option --tolerance expects a number, got 'nan'");
  CHECK(refused(IngestOptionSet::kCompress, {{"color_tolerance", "128"}}, py) ==
        "option color_tolerance expects a whole number from 0 to 127, got '128'");
  CHECK(refused(IngestOptionSet::kCompress, {{"mode", "resample"}, {"tolerance", "0.1"}}, cli) ==
        "--tolerance and --color-tolerance apply to --mode bounded");
  CHECK(refused(IngestOptionSet::kCompress, {{"intensity_tolerance", "32768"}}, py) ==
        "option intensity_tolerance expects a whole number from 0 to 32767, got '32768'");
  CHECK(refused(IngestOptionSet::kCompress, {{"mode", "resample"}, {"intensity_tolerance", "1"}}, cli) ==
        "--intensity-tolerance applies to --mode bounded");
  CHECK(refused(IngestOptionSet::kCompress, {{"mode", "lossy"}}, py) ==
        "mode must be bounded or resample, got 'lossy'");
  CHECK(refused(IngestOptionSet::kCompress, {{"memory", "1M"}}, py) ==
        "memory 1M is below the minimum of 64M");
  CHECK(refused(IngestOptionSet::kCompress, {{"memory", "lots"}}, py) ==
        "memory expects a size such as 512M or 2G, got 'lots'");
  CHECK(refused(IngestOptionSet::kCompress, {{"threads", "-1"}}, py) ==
        "option threads expects a whole number from 0 to 1024, got '-1'");
  CHECK(refused(IngestOptionSet::kCompress, {{"verify", "maybe"}}, py) ==
        "option verify is a flag (true or false), got 'maybe'");
  CHECK(refused(IngestOptionSet::kCompress, {{"height-bits", "16"}}, cli) ==
        "--height-bits 16 needs --codec jpeg2000 (JPEG is 8-bit)");
  CHECK(refused(IngestOptionSet::kCompress, {{"error-target", "1"}, {"mode", "bounded"}}, cli) ==
        "--error-target needs --mode resample");
  CHECK(refused(IngestOptionSet::kCompress, {{"speed", "11"}}, py) == "unknown option speed");
  CHECK(refused(IngestOptionSet::kCompress, {{"mode", "resample"}, {"keep-order", ""}}, cli) ==
        "--keep-order applies to --mode bounded");
  CHECK(refused(IngestOptionSet::kCompress, {{"error_target", "1"}, {"keep_order", "true"}}, py) ==
        "keep_order applies to mode bounded");
  CHECK(refused(IngestOptionSet::kCompress, {{"mode", "resample"}, {"fast-geometry", ""}}, cli) ==
        "--fast-geometry applies to --mode bounded");
  // The archive fixes them for what is appended.
  CHECK(refused(IngestOptionSet::kAppend, {{"keep_order", ""}}, py) == "unknown option keep_order");
  CHECK(refused(IngestOptionSet::kAppend, {{"fast_geometry", ""}}, py) == "unknown option fast_geometry");
  // Append takes only the run's own options: the archive fixes the rest.
  CHECK(refused(IngestOptionSet::kAppend, {{"tolerance", "0.1"}}, py) == "unknown option tolerance");
  CHECK(refused(IngestOptionSet::kStream, {{"assume_crs", ""}}, py) == "unknown option assume_crs");
}

TEST_CASE("ingest options: byte sizes", "[ingest][options]") {
  CHECK(parse_byte_size("2G") == (std::uint64_t{2} << 30));
  CHECK(parse_byte_size("64KiB") == (std::uint64_t{64} << 10));
  CHECK(parse_byte_size("100") == (std::uint64_t{100} << 20));
  CHECK(parse_byte_size("") == 0);
  CHECK(parse_byte_size("-5M") == 0);
  CHECK(parse_byte_size("5Q") == 0);
  CHECK(parse_byte_size("1e30T") == 0);
}

TEST_CASE("bound options: a single chunk's error bound, checked as the ingest checks it", "[ingest][options]") {
  EncodeParams p;
  REQUIRE(apply_bound_options(
              {{"tolerance", "0.005"}, {"color-tolerance", "3"}, {"keep-order", ""}, {"fast-geometry", ""}},
              OptionSpelling::kCli, p)
              .is_ok());
  REQUIRE(p.bound.has_value());
  CHECK(p.bound->step.x == 0.01);
  CHECK(p.bound->step.z == 0.01);
  CHECK(p.bound->color_tolerance == 3);
  CHECK(p.bound->intensity_tolerance == 0);
  CHECK(p.bound->keep_order);
  CHECK(p.bound->fast_geometry);
  // Without a tolerance: nothing set, the others refused.
  EncodeParams maps;
  REQUIRE(apply_bound_options({}, OptionSpelling::kCli, maps).is_ok());
  CHECK_FALSE(maps.bound.has_value());
  for (const char* name : {"color-tolerance", "intensity-tolerance", "keep-order", "fast-geometry"}) {
    INFO(name);
    const bool flag = std::string(name) == "keep-order" || std::string(name) == "fast-geometry";
    const Status s = apply_bound_options({{name, flag ? "" : "2"}}, OptionSpelling::kCli, maps);
    CHECK(s.code() == StatusCode::kInvalidArgument);
    CHECK(s.message().find("applies only with --tolerance") != std::string::npos);
  }
  // Refused values: the ingest's messages; nothing set.
  for (const auto& [name, value] : {std::pair<const char*, const char*>{"tolerance", "0"}, {"tolerance", "-1"},
                                    {"tolerance", "1e308"}, {"tolerance", "x"}, {"color-tolerance", "128"},
                                    {"intensity-tolerance", "32768"}, {"cell", "1"}}) {
    INFO(name << " " << value);
    EncodeParams q;
    std::vector<NamedOption> given = {{name, value}};
    if (std::string(name) != "tolerance") given.push_back({"tolerance", "0.01"});
    CHECK(apply_bound_options(given, OptionSpelling::kCli, q).code() == StatusCode::kInvalidArgument);
    CHECK_FALSE(q.bound.has_value());
  }
}
