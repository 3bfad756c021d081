// CRS decoding and comparison through libgeotiff and PROJ (relief/crs.h).
//
// GeoTIFF keys: the records are checked here (counts and offsets against the
// bytes present), handed to libgeotiff through its in-memory "simple tags"
// TIFF, and normalised by GTIFGetDefn (which looks codes up in PROJ's EPSG
// database). The CRS is then assembled with PROJ's constructors, the way GDAL
// and PDAL read LAS GeoKeys:
//   - a projected CRS code: the database CRS, its linear unit replaced (and
//     the conversion's linear parameters converted) when ProjLinearUnitsGeoKey
//     names another unit (state planes in US feet keyed with the metre code);
//   - user-defined: the geodetic CRS from its GCS code, or from its datum code,
//     or from the ellipsoid and prime meridian; the conversion from its EPSG
//     code or, from the CT method and parameters, as libgeotiff's own PROJ
//     string gives it (libgeotiff maps every CT method); a Cartesian system
//     in the projected linear unit;
//   - vertical: the VerticalCSTypeGeoKey code, else a vertical CRS on the
//     VerticalDatumGeoKey datum in VerticalUnitsGeoKey units, else, as GDAL
//     does, a citation starting "NAVD88" names NAVD88 height in those units;
//     with a horizontal CRS it makes a compound CRS.

#include "relief/crs.h"

#include <geotiff/geo_normalize.h>
#include <geotiff/geo_simpletags.h>
#include <geotiff/geo_tiffp.h>
#include <geotiff/geokeys.h>
#include <geotiff/geotiff.h>
#include <geotiff/geovalues.h>
#include <proj.h>
#include <proj_experimental.h>

#include <algorithm>
#include <bit>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <initializer_list>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <type_traits>
#include <utility>
#include <vector>

namespace relief {

namespace {

constexpr std::uint16_t kKeyDirectoryTag = 34735;
constexpr std::uint16_t kDoubleParamsTag = 34736;
constexpr std::uint16_t kAsciiParamsTag = 34737;
constexpr std::size_t kDirectoryHeaderWords = 4;
constexpr std::size_t kWordsPerKey = 4;
// GeoTIFF: 0 is "undefined", 32767 "user-defined"; neither is a code.
constexpr int kUserDefinedCode = 32767;
// GDAL's name for a datum the keys do not name: the same CRS read by GDAL
// (PDAL) and here compares equal, and PROJ compares datum names.
constexpr char kUnnamedDatum[] = "unnamed";
constexpr char kLegacyKeysPrefix[] = "GeoTIFF keys:";
// EPSG vertical CRSs GDAL picks for an "NAVD88..." citation, by unit.
constexpr int kNavd88Metre = 5703;
constexpr int kNavd88UsFoot = 6360;
constexpr int kNavd88Foot = 8228;
constexpr int kUnitMetre = 9001;
constexpr int kUnitFoot = 9002;
constexpr int kUnitUsFoot = 9003;
constexpr double kDegree = 0.017453292519943295;
// proj_identify confidence that means "the same CRS" (100: names match too,
// 70: equivalent under another name).
constexpr int kIdentifiedConfidence = 70;

// Little-endian fields of the LAS records, whatever the host order.
template <typename T>
T load_le(const std::uint8_t* p) {
  std::uint64_t v = 0;
  for (std::size_t i = 0; i < sizeof(T); ++i) v |= static_cast<std::uint64_t>(p[i]) << (8 * i);
  if constexpr (std::is_floating_point_v<T>) {
    return std::bit_cast<T>(v);
  } else {
    return static_cast<T>(v);
  }
}

void store_le(std::uint8_t* p, std::uint16_t v) {
  p[0] = static_cast<std::uint8_t>(v);
  p[1] = static_cast<std::uint8_t>(v >> 8);
}

bool is_code(int v) { return v > 0 && v != kUserDefinedCode; }

// ---- PROJ handles

struct ContextDeleter {
  void operator()(PJ_CONTEXT* c) const { proj_context_destroy(c); }
};
struct PjDeleter {
  void operator()(PJ* p) const { proj_destroy(p); }
};
using Context = std::unique_ptr<PJ_CONTEXT, ContextDeleter>;
using Pj = std::unique_ptr<PJ, PjDeleter>;

// One context per call: PROJ contexts are not shared across threads, and
// ingest reads inputs on several.
Context new_context() {
  // libgeotiff looks some codes up through PROJ's default context, which
  // would print "not found" lines for a file's unknown codes on stderr.
  static std::once_flag quiet_default;
  std::call_once(quiet_default, [] { proj_log_level(nullptr, PJ_LOG_NONE); });
  Context ctx(proj_context_create());
  // Errors come back as statuses, not as lines on stderr.
  if (ctx) proj_log_level(ctx.get(), PJ_LOG_NONE);
  return ctx;
}

std::string last_error(PJ_CONTEXT* ctx) {
  const int e = proj_context_errno(ctx);
  const char* s = e != 0 ? proj_context_errno_string(ctx, e) : nullptr;
  return s != nullptr ? std::string(s) : std::string("not understood");
}

Pj from_database(PJ_CONTEXT* ctx, int code, PJ_CATEGORY category) {
  const std::string text = std::to_string(code);
  return Pj(proj_create_from_database(ctx, "EPSG", text.c_str(), category, 0, nullptr));
}

Result<std::string> as_wkt2(PJ_CONTEXT* ctx, const PJ* crs, const std::string& where) {
  const char* const options[] = {"MULTILINE=NO", nullptr};
  const char* w = proj_as_wkt(ctx, crs, PJ_WKT2_2019, options);
  if (w == nullptr) return format_error(where + ": the CRS cannot be written as WKT2: " + last_error(ctx));
  return std::string(w);
}

// ---- GeoTIFF records

std::uint16_t word(const std::vector<std::uint8_t>& b, std::size_t i) { return load_le<std::uint16_t>(b.data() + 2 * i); }

// Every count and offset of the directory against the bytes present.
Status check_directory(const GeoTiffRecords& r, const std::string& where) {
  const std::string what = where + ": GeoTIFF GeoKeyDirectory";
  const std::size_t words = r.keys.size() / 2;
  if (words < kDirectoryHeaderWords) {
    return format_error(what + " of " + std::to_string(r.keys.size()) + " bytes is shorter than its 8-byte header");
  }
  if (word(r.keys, 0) != 1) {
    return format_error(what + " has KeyDirectoryVersion " + std::to_string(word(r.keys, 0)) + ", expected 1");
  }
  const std::size_t declared = word(r.keys, 3);
  const std::size_t room = (words - kDirectoryHeaderWords) / kWordsPerKey;
  if (declared > room) {
    return format_error(what + " declares " + std::to_string(declared) + " keys but its " +
                        std::to_string(r.keys.size()) + " bytes hold " + std::to_string(room));
  }
  const std::size_t doubles = r.doubles.size() / 8;
  for (std::size_t k = 0; k < declared; ++k) {
    const std::size_t at = kDirectoryHeaderWords + kWordsPerKey * k;
    const std::uint16_t id = word(r.keys, at);
    const std::uint16_t location = word(r.keys, at + 1);
    const std::size_t count = word(r.keys, at + 2);
    const std::size_t offset = word(r.keys, at + 3);
    const std::string key = what + ": key " + std::to_string(id);
    std::size_t available = 0;
    const char* in = "";
    if (location == 0) {
      if (count != 1) return format_error(key + " holds its value inline but declares " + std::to_string(count) + " values");
      continue;
    } else if (location == kDoubleParamsTag) {
      available = doubles;
      in = "GeoDoubleParams values";
    } else if (location == kAsciiParamsTag) {
      available = r.ascii.size();
      in = "GeoAsciiParams bytes";
    } else if (location == kKeyDirectoryTag) {
      available = words;
      in = "GeoKeyDirectory words";
    } else {
      return format_error(key + " refers to TIFF tag " + std::to_string(location) +
                          ", which a LAS file does not have");
    }
    if (count == 0 || offset > available || count > available - offset) {
      return format_error(key + " refers to " + std::to_string(count) + " values at offset " + std::to_string(offset) +
                          " but there are " + std::to_string(available) + " " + in);
    }
  }
  for (std::size_t i = 0; i < doubles; ++i) {
    if (!std::isfinite(load_le<double>(r.doubles.data() + 8 * i))) {
      return format_error(where + ": GeoTIFF GeoDoubleParams value " + std::to_string(i) + " is not finite");
    }
  }
  return Status::ok();
}

struct StDeleter {
  void operator()(ST_TIFF* t) const { ST_Destroy(t); }
};
struct GtifDeleter {
  void operator()(GTIF* g) const { GTIFFree(g); }
};
struct DefnDeleter {
  void operator()(GTIFDefn* d) const { GTIFFreeDefn(d); }
};

void quiet_geotiff_error(GTIF*, int, const char*, ...) {}

// Value of a SHORT key, -1 when absent.
int short_key(GTIF* gt, geokey_t key) {
  unsigned short v = 0;
  return GTIFKeyGetSHORT(gt, key, &v, 0, 1) == 1 ? static_cast<int>(v) : -1;
}

std::string ascii_key(GTIF* gt, geokey_t key) {
  char buffer[1024] = {};
  if (GTIFKeyGetASCII(gt, key, buffer, sizeof buffer) <= 0) return "";
  std::string s(buffer, ::strnlen(buffer, sizeof buffer));
  // Citations end with '|' (the GeoTIFF ASCII separator); ESRI writers add
  // "|GCS Name = ...|" parts after the name itself.
  const std::size_t bar = s.find('|');
  if (bar != std::string::npos) s.resize(bar);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\0')) s.pop_back();
  return s;
}

// The "<tag>X|" part of an ESRI-style GeogCitation ("GCS Name = ",
// "Datum = "); empty when absent.
std::string citation_part(GTIF* gt, const std::string& tag) {
  char buffer[1024] = {};
  if (GTIFKeyGetASCII(gt, GeogCitationGeoKey, buffer, sizeof buffer) <= 0) return "";
  const std::string s(buffer, ::strnlen(buffer, sizeof buffer));
  const std::size_t at = s.find(tag);
  if (at == std::string::npos) return "";
  const std::size_t end = s.find('|', at);
  return s.substr(at + tag.size(), end == std::string::npos ? std::string::npos : end - at - tag.size());
}

// The GCS name of an ESRI-style GeogCitation, else the citation.
std::string gcs_name(GTIF* gt) {
  std::string name = citation_part(gt, "GCS Name = ");
  if (name.empty()) name = ascii_key(gt, GeogCitationGeoKey);
  return name.empty() ? "unknown" : name;
}

std::string length_unit_name(PJ_CONTEXT* ctx, int code, double in_metres) {
  if (code == kUnitMetre || in_metres == 1.0) return "metre";
  char* name = nullptr;
  if (is_code(code) && GTIFGetUOMLengthInfoEx(ctx, code, &name, nullptr) && name != nullptr) {
    std::string s(name);
    GTIFFreeMemory(name);
    return s;
  }
  return "unknown";
}

Result<Pj> geodetic_crs(PJ_CONTEXT* ctx, GTIF* gt, const GTIFDefn& d, const std::string& where) {
  if (is_code(d.GCS)) {
    Pj g = from_database(ctx, d.GCS, PJ_CATEGORY_CRS);
    if (g) return g;
  }
  const std::string name = gcs_name(gt);
  Pj cs(proj_create_ellipsoidal_2D_cs(ctx, PJ_ELLPS2D_LATITUDE_LONGITUDE, "degree", kDegree));
  if (is_code(d.Datum)) {
    Pj datum = from_database(ctx, d.Datum, PJ_CATEGORY_DATUM);
    if (datum) {
      Pj g(proj_create_geographic_crs_from_datum(ctx, name.c_str(), datum.get(), cs.get()));
      if (g) return g;
    }
  }
  {
    // ESRI writers name a user-defined datum in the citation ("Datum =
    // D_North_American_1983"); PROJ's database knows those names.
    const std::string esri = citation_part(gt, "Datum = ");
    if (!esri.empty()) {
      const PJ_TYPE types[] = {PJ_TYPE_GEODETIC_REFERENCE_FRAME};
      PJ_OBJ_LIST* found = proj_create_from_name(ctx, nullptr, esri.c_str(), types, 1, 1, 1, nullptr);
      Pj datum(found && proj_list_get_count(found) > 0 ? proj_list_get(ctx, found, 0) : nullptr);
      proj_list_destroy(found);
      if (datum) {
        // The ESRI name may be an alias; an EPSG code carries the EPSG name.
        const char* code = proj_get_id_code(datum.get(), 0);
        Pj epsg = code ? from_database(ctx, std::atoi(code), PJ_CATEGORY_DATUM) : Pj();
        if (epsg) datum = std::move(epsg);
        Pj ellipsoid(proj_get_ellipsoid(ctx, datum.get()));
        double a = 0;
        if (ellipsoid && proj_ellipsoid_get_parameters(ctx, ellipsoid.get(), &a, nullptr, nullptr, nullptr) &&
            (!(d.SemiMajor > 0) || std::fabs(a - d.SemiMajor) < 1e-3)) {
          Pj g(proj_create_geographic_crs_from_datum(ctx, name.c_str(), datum.get(), cs.get()));
          if (g) return g;
        }
      }
    }
  }
  if (!(d.SemiMajor > 0) || !(d.SemiMinor > 0) || d.SemiMinor > d.SemiMajor) {
    return format_error(where + ": GeoTIFF keys: the ellipsoid is missing or invalid");
  }
  const double inv_flattening = d.SemiMajor == d.SemiMinor ? 0.0 : d.SemiMajor / (d.SemiMajor - d.SemiMinor);
  std::string ellipsoid = "unknown";
  char* text = nullptr;
  if (is_code(d.Ellipsoid) && GTIFGetEllipsoidInfoEx(ctx, d.Ellipsoid, &text, nullptr, nullptr) && text) {
    ellipsoid = text;
    GTIFFreeMemory(text);
  }
  std::string meridian = "Greenwich";
  text = nullptr;
  if (is_code(d.PM) && GTIFGetPMInfoEx(ctx, d.PM, &text, nullptr) && text) {
    meridian = text;
    GTIFFreeMemory(text);
  } else if (d.PMLongToGreenwich != 0) {
    meridian = "unknown";
  }
  Pj g(proj_create_geographic_crs(ctx, name.c_str(), kUnnamedDatum, ellipsoid.c_str(), d.SemiMajor, inv_flattening,
                                  meridian.c_str(), d.PMLongToGreenwich, "degree", kDegree, cs.get()));
  if (!g) return format_error(where + ": GeoTIFF keys: the geographic CRS cannot be built: " + last_error(ctx));
  return g;
}

// Replaces the linear unit of a projected CRS (axes and conversion
// parameters) when `code` names another one.
Result<Pj> with_linear_unit(PJ_CONTEXT* ctx, Pj crs, int code, const std::string& where) {
  if (!is_code(code)) return crs;
  char* name = nullptr;
  double in_metres = 0;
  if (!GTIFGetUOMLengthInfoEx(ctx, code, &name, &in_metres) || !(in_metres > 0)) {
    if (name) GTIFFreeMemory(name);
    return format_error(where + ": GeoTIFF keys: unknown linear unit " + std::to_string(code));
  }
  const std::string unit = name ? name : "unknown";
  if (name) GTIFFreeMemory(name);
  Pj cs(proj_crs_get_coordinate_system(ctx, crs.get()));
  double factor = 0;
  if (cs && proj_cs_get_axis_info(ctx, cs.get(), 0, nullptr, nullptr, nullptr, &factor, nullptr, nullptr, nullptr) &&
      std::fabs(factor - in_metres) <= 1e-12 * in_metres) {
    return crs;
  }
  const std::string code_text = std::to_string(code);
  Pj params(proj_crs_alter_parameters_linear_unit(ctx, crs.get(), unit.c_str(), in_metres, "EPSG", code_text.c_str(), 1));
  if (!params) return format_error(where + ": GeoTIFF keys: cannot change the unit to " + unit + ": " + last_error(ctx));
  Pj axes(proj_crs_alter_cs_linear_unit(ctx, params.get(), unit.c_str(), in_metres, "EPSG", code_text.c_str()));
  if (!axes) return format_error(where + ": GeoTIFF keys: cannot change the unit to " + unit + ": " + last_error(ctx));
  // The database code named the CRS in its own unit: it no longer applies.
  Pj unnamed(proj_alter_id(ctx, axes.get(), "", ""));
  return unnamed ? std::move(unnamed) : std::move(axes);
}

// GTIFGetProj4Defn prints the parameters with "%f"-style formats into fixed
// buffers: a huge value (1e300 from a hostile file) overflows them (glibc's
// fortify check aborts the process). No real ellipsoid, projection parameter
// or unit comes near these bounds.
Status check_printable(const GTIFDefn& d, const std::string& where) {
  constexpr double kMaxParameter = 1e9;  // metres or degrees
  const auto bad = [&](double v) { return !std::isfinite(v) || std::fabs(v) > kMaxParameter; };
  std::string what;
  if (bad(d.SemiMajor) || bad(d.SemiMinor)) what = "ellipsoid axis";
  if (bad(d.PMLongToGreenwich)) what = "prime meridian";
  if (bad(d.UOMLengthInMeters) || bad(d.UOMAngleInDegrees)) what = "unit size";
  for (int i = 0; i < d.nParms && i < MAX_GTIF_PROJPARMS; ++i) {
    if (bad(d.ProjParm[i])) what = "projection parameter (key " + std::to_string(d.ProjParmId[i]) + ")";
  }
#if !defined(GEO_NORMALIZE_DISABLE_TOWGS84)
  for (int i = 0; i < d.TOWGS84Count && i < 7; ++i) {
    if (bad(d.TOWGS84[i])) what = "TOWGS84 value";
  }
#endif
  if (what.empty()) return Status::ok();
  return format_error(where + ": GeoTIFF keys: implausible " + what + " (beyond 1e9 in magnitude, or not finite)");
}

// The value libgeotiff normalised to metres for the first of `keys` present.
std::optional<double> defn_parameter(const GTIFDefn& d, std::initializer_list<int> keys) {
  for (int key : keys) {
    for (int i = 0; i < d.nParms && i < MAX_GTIF_PROJPARMS; ++i) {
      if (d.ProjParmId[i] == key) return d.ProjParm[i];
    }
  }
  return std::nullopt;
}

// The conversion again, with the false easting and northing in the
// projected unit from the keys' own doubles: the PROJ string prints them in
// metres to 15 digits, which moves a 200000 ftUS easting by 3e-4 ft.
Result<Pj> exact_false_origin(PJ_CONTEXT* ctx, Pj conversion, const GTIFDefn& d, const std::string& unit,
                              double in_metres, const std::string& where) {
  const char* method = nullptr;
  const char* method_auth = nullptr;
  const char* method_code = nullptr;
  if (!proj_coordoperation_get_method_info(ctx, conversion.get(), &method, &method_auth, &method_code)) {
    return conversion;
  }
  const int count = proj_coordoperation_get_param_count(ctx, conversion.get());
  std::vector<PJ_PARAM_DESCRIPTION> params(static_cast<std::size_t>(std::max(count, 0)));
  for (int i = 0; i < count; ++i) {
    PJ_PARAM_DESCRIPTION& p = params[static_cast<std::size_t>(i)];
    const char* category = nullptr;
    if (!proj_coordoperation_get_param(ctx, conversion.get(), i, &p.name, &p.auth_name, &p.code, &p.value, nullptr,
                                       &p.unit_conv_factor, &p.unit_name, nullptr, nullptr, &category)) {
      return format_error(where + ": GeoTIFF keys: cannot read back projection parameter " + std::to_string(i));
    }
    const std::string_view cat = category ? category : "";
    p.unit_type = cat == "angular" ? PJ_UT_ANGULAR : cat == "linear" ? PJ_UT_LINEAR
                : cat == "scale" ? PJ_UT_SCALE : cat == "time" ? PJ_UT_TIME : PJ_UT_PARAMETRIC;
    if (p.unit_type != PJ_UT_LINEAR || p.code == nullptr) continue;
    const std::string_view code = p.code;
    std::optional<double> metres;
    if (code == "8806" || code == "8826" || code == "8816") {
      metres = defn_parameter(d, {ProjFalseEastingGeoKey, ProjFalseOriginEastingGeoKey, ProjCenterEastingGeoKey});
    } else if (code == "8807" || code == "8827" || code == "8817") {
      metres = defn_parameter(d, {ProjFalseNorthingGeoKey, ProjFalseOriginNorthingGeoKey, ProjCenterNorthingGeoKey});
    }
    if (!metres) continue;
    // libgeotiff multiplied the key's value by the unit size; dividing
    // gives the key's value back to the last bit or so.
    p.value = *metres / in_metres;
    p.unit_name = unit.c_str();
    p.unit_conv_factor = in_metres;
  }
  Pj rebuilt(proj_create_conversion(ctx, "unknown", nullptr, nullptr, method, method_auth, method_code, count,
                                    params.data()));
  if (!rebuilt) return conversion;
  return rebuilt;
}

Result<Pj> projected_crs(PJ_CONTEXT* ctx, GTIF* gt, GTIFDefn& d, const std::string& where) {
  if (is_code(d.PCS)) {
    Pj p = from_database(ctx, d.PCS, PJ_CATEGORY_CRS);
    if (p) return with_linear_unit(ctx, std::move(p), short_key(gt, ProjLinearUnitsGeoKey), where);
  }
  RELIEF_ASSIGN_OR_RETURN(Pj geodetic, geodetic_crs(ctx, gt, d, where));
  Pj conversion;
  if (is_code(d.ProjCode)) conversion = from_database(ctx, d.ProjCode, PJ_CATEGORY_COORDINATE_OPERATION);
  if (!conversion) {
    RELIEF_RETURN_IF_ERROR(check_printable(d, where));
    // libgeotiff's PROJ string carries the method and its parameters (in
    // metres and degrees); only the conversion is taken from it.
    char* text = GTIFGetProj4Defn(&d);
    if (text == nullptr) return format_error(where + ": GeoTIFF keys: the projection is not understood");
    std::string proj_string(text);
    GTIFFreeMemory(text);
    proj_string += " +type=crs";
    Pj from_string(proj_create(ctx, proj_string.c_str()));
    if (from_string) {
      Pj base = proj_get_type(from_string.get()) == PJ_TYPE_BOUND_CRS
                    ? Pj(proj_get_source_crs(ctx, from_string.get()))
                    : std::move(from_string);
      if (base) conversion.reset(proj_crs_get_coordoperation(ctx, base.get()));
    }
    if (!conversion) {
      return format_error(where + ": GeoTIFF keys: projection method " + std::to_string(d.CTProjection) +
                          " is not understood (" + proj_string + ")");
    }
  }
  const std::string unit = length_unit_name(ctx, d.UOMLength, d.UOMLengthInMeters);
  const double in_metres = d.UOMLengthInMeters > 0 ? d.UOMLengthInMeters : 1.0;
  if (!is_code(d.ProjCode)) {
    RELIEF_ASSIGN_OR_RETURN(conversion, exact_false_origin(ctx, std::move(conversion), d, unit, in_metres, where));
  }
  Pj cs(proj_create_cartesian_2D_cs(ctx, PJ_CART2D_EASTING_NORTHING, unit.c_str(), in_metres));
  std::string name = ascii_key(gt, PCSCitationGeoKey);
  if (name.empty()) name = ascii_key(gt, GTCitationGeoKey);
  if (name.empty()) name = "unnamed";
  Pj p(proj_create_projected_crs(ctx, name.c_str(), geodetic.get(), conversion.get(), cs.get()));
  if (!p) return format_error(where + ": GeoTIFF keys: the projected CRS cannot be built: " + last_error(ctx));
  // A conversion from the database keeps its own linear unit in the
  // parameters; the axes say which unit the coordinates are in.
  return p;
}

// The vertical CRS the keys describe; null when they describe none.
Result<Pj> vertical_crs(PJ_CONTEXT* ctx, GTIF* gt, const std::string& where) {
  const int code = short_key(gt, VerticalCSTypeGeoKey);
  const int datum = short_key(gt, VerticalDatumGeoKey);
  const int units = short_key(gt, VerticalUnitsGeoKey);
  const std::string citation = ascii_key(gt, VerticalCitationGeoKey);
  if (is_code(code)) {
    Pj v = from_database(ctx, code, PJ_CATEGORY_CRS);
    if (!v) return format_error(where + ": GeoTIFF keys: unknown vertical CRS EPSG:" + std::to_string(code));
    return v;
  }
  const int unit_code = is_code(units) ? units : kUnitMetre;
  if (citation.rfind("NAVD88", 0) == 0 && !is_code(datum)) {
    const int navd = unit_code == kUnitUsFoot ? kNavd88UsFoot : unit_code == kUnitFoot ? kNavd88Foot
                                                  : unit_code == kUnitMetre ? kNavd88Metre : 0;
    if (navd != 0) {
      Pj v = from_database(ctx, navd, PJ_CATEGORY_CRS);
      if (v) return v;
    }
  }
  if (!is_code(datum)) return Pj();
  char* name = nullptr;
  double in_metres = 0;
  if (!GTIFGetUOMLengthInfoEx(ctx, unit_code, &name, &in_metres) || !(in_metres > 0)) {
    if (name) GTIFFreeMemory(name);
    return format_error(where + ": GeoTIFF keys: unknown vertical unit " + std::to_string(unit_code));
  }
  const std::string unit = name ? name : "unknown";
  if (name) GTIFFreeMemory(name);
  const std::string datum_code = std::to_string(datum);
  Pj datum_object = from_database(ctx, datum, PJ_CATEGORY_DATUM);
  if (!datum_object) return format_error(where + ": GeoTIFF keys: unknown vertical datum EPSG:" + datum_code);
  const std::string datum_name = proj_get_name(datum_object.get());
  const std::string crs_name = citation.empty() ? datum_name + " height" : citation;
  Pj v(proj_create_vertical_crs_ex(ctx, crs_name.c_str(), datum_name.c_str(), "EPSG", datum_code.c_str(), unit.c_str(), in_metres,
                                   nullptr, nullptr, nullptr, nullptr, nullptr));
  if (!v) return format_error(where + ": GeoTIFF keys: vertical datum " + datum_code + ": " + last_error(ctx));
  return v;
}

Result<CrsDefinition> geotiff_to_wkt2(PJ_CONTEXT* ctx, const GeoTiffRecords& r, const std::string& where) {
  RELIEF_RETURN_IF_ERROR(check_directory(r, where));
  CrsDefinition out;
  out.source = geotiff_source_text(r);

  // libgeotiff's simple tags copy what they are given, in host order.
  std::unique_ptr<ST_TIFF, StDeleter> tiff(ST_Create());
  if (!tiff) return internal_error(where + ": libgeotiff: out of memory");
  const std::size_t words = kDirectoryHeaderWords + kWordsPerKey * word(r.keys, 3);
  std::vector<unsigned short> keys(words);
  for (std::size_t i = 0; i < words; ++i) keys[i] = word(r.keys, i);
  ST_SetKey(tiff.get(), kKeyDirectoryTag, static_cast<int>(words), STT_SHORT, keys.data());
  std::vector<double> doubles(r.doubles.size() / 8);
  for (std::size_t i = 0; i < doubles.size(); ++i) doubles[i] = load_le<double>(r.doubles.data() + 8 * i);
  if (!doubles.empty()) {
    ST_SetKey(tiff.get(), kDoubleParamsTag, static_cast<int>(doubles.size()), STT_DOUBLE, doubles.data());
  }
  // NUL-terminated, whatever the record holds.
  std::string ascii(reinterpret_cast<const char*>(r.ascii.data()), r.ascii.size());
  if (!ascii.empty()) {
    ST_SetKey(tiff.get(), kAsciiParamsTag, static_cast<int>(ascii.size() + 1), STT_ASCII, ascii.data());
  }
  TIFFMethod methods;
  GTIFSetSimpleTagsMethods(&methods);
  std::unique_ptr<GTIF, GtifDeleter> gt(GTIFNewWithMethodsEx(tiff.get(), &methods, quiet_geotiff_error, nullptr));
  if (!gt) return format_error(where + ": GeoTIFF keys: libgeotiff cannot read the key directory");
  GTIFAttachPROJContext(gt.get(), ctx);
  std::unique_ptr<GTIFDefn, DefnDeleter> defn(GTIFAllocDefn());
  if (!defn) return internal_error(where + ": libgeotiff: out of memory");
  const bool defined = GTIFGetDefn(gt.get(), defn.get()) != 0;

  Pj horizontal;
  if (defined && defn->Model == ModelTypeProjected) {
    RELIEF_ASSIGN_OR_RETURN(horizontal, projected_crs(ctx, gt.get(), *defn, where));
  } else if (defined && defn->Model == ModelTypeGeographic) {
    RELIEF_ASSIGN_OR_RETURN(horizontal, geodetic_crs(ctx, gt.get(), *defn, where));
  }
  RELIEF_ASSIGN_OR_RETURN(Pj vertical, vertical_crs(ctx, gt.get(), where));
  Pj crs;
  if (horizontal && vertical) {
    const std::string citation = ascii_key(gt.get(), VerticalCitationGeoKey);
    const std::string name = std::string(proj_get_name(horizontal.get())) + " + " +
                             (citation.empty() ? std::string(proj_get_name(vertical.get())) : citation);
    crs.reset(proj_create_compound_crs(ctx, name.c_str(), horizontal.get(), vertical.get()));
    if (!crs) return format_error(where + ": GeoTIFF keys: the compound CRS cannot be built: " + last_error(ctx));
  } else {
    crs = horizontal ? std::move(horizontal) : std::move(vertical);
  }
  if (!crs) return out;  // well-formed keys that name no CRS
  RELIEF_ASSIGN_OR_RETURN(out.wkt, as_wkt2(ctx, crs.get(), where));
  return out;
}

// "GeoTIFF keys: 1024=1, 3072=26910" (archives before the crs module) as records.
bool parse_legacy_keys(std::string_view text, GeoTiffRecords& out) {
  text.remove_prefix(sizeof kLegacyKeysPrefix - 1);
  std::vector<std::pair<unsigned, unsigned>> keys;
  while (!text.empty()) {
    const std::size_t comma = std::min(text.find(','), text.size());
    std::string_view item = text.substr(0, comma);
    text.remove_prefix(std::min(comma + 1, text.size()));
    const std::size_t eq = item.find('=');
    if (eq == std::string_view::npos) return false;
    unsigned id = 0;
    unsigned value = 0;
    const std::string a(item.substr(0, eq));
    const std::string b(item.substr(eq + 1));
    if (std::sscanf(a.c_str(), "%u", &id) != 1 || std::sscanf(b.c_str(), "%u", &value) != 1 || id > 65535 ||
        value > 65535) {
      return false;
    }
    keys.emplace_back(id, value);
  }
  std::sort(keys.begin(), keys.end());
  std::vector<std::uint16_t> words = {1, 1, 0, static_cast<std::uint16_t>(keys.size())};
  for (const auto& [id, value] : keys) {
    words.insert(words.end(), {static_cast<std::uint16_t>(id), 0, 1, static_cast<std::uint16_t>(value)});
  }
  out.keys.resize(2 * words.size());
  for (std::size_t i = 0; i < words.size(); ++i) store_le(out.keys.data() + 2 * i, words[i]);
  return true;
}

// WKT: a bracket anywhere outside PROJJSON (PROJ strings, "AUTH:CODE", URNs
// and CRS names hold none), or at the start a keyword, '(' and a quote (WKT
// allows either delimiter, and every CRS keyword's first value is its quoted
// name; CRS names hold parentheses, as "NAD83(HARN)", but no quotes).
bool looks_like_wkt(std::string_view text) {
  std::size_t i = 0;
  while (i < text.size() && std::isspace(static_cast<unsigned char>(text[i]))) ++i;
  if (i < text.size() && text[i] == '{') return false;
  if (text.find('[') != std::string_view::npos) return true;
  const std::size_t word = i;
  while (i < text.size() && (std::isalnum(static_cast<unsigned char>(text[i])) || text[i] == '_')) ++i;
  return i > word && std::isalpha(static_cast<unsigned char>(text[word])) && i + 1 < text.size() &&
         text[i] == '(' && text[i + 1] == '"';
}

// PROJ's WKT parser (WKT 1 or 2, lenient), nothing else.
Result<Pj> parse_wkt(PJ_CONTEXT* ctx, const std::string& text, const std::string& where) {
  PROJ_STRING_LIST errors = nullptr;
  Pj p(proj_create_from_wkt(ctx, text.c_str(), nullptr, nullptr, &errors));
  // PROJ's first complaint (where the WKT goes wrong), or the context's.
  const std::string why = errors != nullptr && errors[0] != nullptr ? std::string(errors[0]) : last_error(ctx);
  proj_string_list_destroy(errors);
  if (!p || !proj_is_crs(p.get())) {
    return format_error(where + ": not a WKT coordinate reference system PROJ understands" +
                        (p ? std::string() : ": " + why));
  }
  return p;
}

Result<Pj> parse_any(PJ_CONTEXT* ctx, const std::string& text, const std::string& where) {
  if (text.empty()) return invalid_argument(where + ": no CRS");
  GeoTiffRecords records;
  const bool geotiff = parse_geotiff_source_text(text, records) ||
                       (text.rfind(kLegacyKeysPrefix, 0) == 0 && parse_legacy_keys(text, records));
  if (geotiff) {
    RELIEF_ASSIGN_OR_RETURN(CrsDefinition d, geotiff_to_wkt2(ctx, records, where));
    if (d.wkt.empty()) return format_error(where + ": the GeoTIFF keys name no CRS");
    Pj p(proj_create(ctx, d.wkt.c_str()));
    if (!p) return internal_error(where + ": PROJ cannot read its own WKT2: " + last_error(ctx));
    return p;
  }
  // WKT-shaped text (a keyword and a bracket: a LAS WKT VLR, an archive's
  // CRS) goes to PROJ's WKT parser alone. proj_create() would take text its
  // parser rejects for a name and search PROJ's database for it, which takes
  // ~1 s for a damaged WKT of a few KB (a LAS file whose VLR lost its first
  // bytes, found by fuzzing) and can match an unrelated CRS by name.
  if (looks_like_wkt(text)) return parse_wkt(ctx, text, where);
  Pj p(proj_create(ctx, text.c_str()));
  if (!p || !proj_is_crs(p.get())) {
    return format_error(where + ": not a coordinate reference system PROJ understands" +
                        (p ? std::string() : ": " + last_error(ctx)));
  }
  return p;
}

const char* kHex = "0123456789abcdef";

void append_hex(std::string& out, const std::vector<std::uint8_t>& bytes) {
  for (std::uint8_t b : bytes) {
    out += kHex[b >> 4];
    out += kHex[b & 15];
  }
}

bool read_hex(std::string_view s, std::vector<std::uint8_t>& out) {
  if (s.size() % 2 != 0) return false;
  out.clear();
  out.reserve(s.size() / 2);
  auto nibble = [](char c) -> int {
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
  };
  for (std::size_t i = 0; i < s.size(); i += 2) {
    const int hi = nibble(s[i]);
    const int lo = nibble(s[i + 1]);
    if (hi < 0 || lo < 0) return false;
    out.push_back(static_cast<std::uint8_t>(hi * 16 + lo));
  }
  return true;
}

std::string_view trim(std::string_view s) {
  while (!s.empty() && s.front() == ' ') s.remove_prefix(1);
  while (!s.empty() && s.back() == ' ') s.remove_suffix(1);
  return s;
}

// PROJ's answers depend only on the text asked about (and proj.db, which does
// not change under a running process), and each costs milliseconds: a reader
// of many tiles in one CRS asks the same questions once per file (a thousand
// tiles: seconds; under the sanitizers far more). The last few successful
// answers are kept, per question; errors are not (they name the caller's file).
template <typename V>
class Memo {
 public:
  template <typename F>
  Result<V> get(const std::string& key, F&& compute) {
    {
      std::lock_guard<std::mutex> lock(mu_);
      for (const auto& [k, v] : entries_) {
        if (k == key) return v;
      }
    }
    Result<V> r = compute();
    if (r.is_ok()) {
      std::lock_guard<std::mutex> lock(mu_);
      if (entries_.size() >= kEntries) entries_.erase(entries_.begin());
      entries_.emplace_back(key, *r);
    }
    return r;
  }

 private:
  static constexpr std::size_t kEntries = 16;
  std::mutex mu_;
  std::vector<std::pair<std::string, V>> entries_;
};

}  // namespace

std::string geotiff_source_text(const GeoTiffRecords& records) {
  std::string out = kGeoTiffSourcePrefix;
  out += " 34735=";
  append_hex(out, records.keys);
  if (!records.doubles.empty()) {
    out += "; 34736=";
    append_hex(out, records.doubles);
  }
  if (!records.ascii.empty()) {
    out += "; 34737=";
    append_hex(out, records.ascii);
  }
  return out;
}

bool parse_geotiff_source_text(const std::string& text, GeoTiffRecords& out) {
  const std::string_view prefix = kGeoTiffSourcePrefix;
  if (text.rfind(prefix, 0) != 0) return false;
  std::string_view rest = std::string_view(text).substr(prefix.size());
  out = GeoTiffRecords{};
  bool have_keys = false;
  while (!rest.empty()) {
    const std::size_t semi = std::min(rest.find(';'), rest.size());
    const std::string_view item = trim(rest.substr(0, semi));
    rest.remove_prefix(std::min(semi + 1, rest.size()));
    const std::size_t eq = item.find('=');
    if (eq == std::string_view::npos) return false;
    const std::string_view tag = item.substr(0, eq);
    std::vector<std::uint8_t>* target = tag == "34735"   ? &out.keys
                                        : tag == "34736" ? &out.doubles
                                        : tag == "34737" ? &out.ascii
                                                         : nullptr;
    if (target == nullptr || !read_hex(item.substr(eq + 1), *target)) return false;
    have_keys = have_keys || target == &out.keys;
  }
  return have_keys;
}

namespace {

Result<CrsSummary> describe_uncached(const std::string& text, const std::string& where) {
  Context ctx = new_context();
  if (!ctx) return internal_error(where + ": PROJ: cannot create a context");
  RELIEF_ASSIGN_OR_RETURN(Pj crs, parse_any(ctx.get(), text, where));
  CrsSummary s;
  const char* name = proj_get_name(crs.get());
  s.name = name ? name : "";
  RELIEF_ASSIGN_OR_RETURN(s.wkt, as_wkt2(ctx.get(), crs.get(), where));
  const char* auth = proj_get_id_auth_name(crs.get(), 0);
  const char* code = proj_get_id_code(crs.get(), 0);
  if (auth && code && std::string_view(auth) == "EPSG") {
    s.epsg = std::atoi(code);
  } else {
    int* confidence = nullptr;
    PJ_OBJ_LIST* found = proj_identify(ctx.get(), crs.get(), "EPSG", nullptr, &confidence);
    if (found && proj_list_get_count(found) > 0 && confidence && confidence[0] >= kIdentifiedConfidence) {
      Pj best(proj_list_get(ctx.get(), found, 0));
      const char* best_code = best ? proj_get_id_code(best.get(), 0) : nullptr;
      if (best_code) s.epsg = std::atoi(best_code);
    }
    proj_int_list_destroy(confidence);
    proj_list_destroy(found);
  }
  // Longitude/latitude axes: a geographic CRS, or one as the first part of
  // a compound CRS.
  Pj horizontal = proj_get_type(crs.get()) == PJ_TYPE_COMPOUND_CRS ? Pj(proj_crs_get_sub_crs(ctx.get(), crs.get(), 0))
                                                                   : Pj(proj_clone(ctx.get(), crs.get()));
  if (horizontal && proj_get_type(horizontal.get()) == PJ_TYPE_BOUND_CRS) {
    horizontal.reset(proj_get_source_crs(ctx.get(), horizontal.get()));
  }
  if (horizontal) {
    const PJ_TYPE t = proj_get_type(horizontal.get());
    s.geographic = t == PJ_TYPE_GEOGRAPHIC_2D_CRS || t == PJ_TYPE_GEOGRAPHIC_3D_CRS;
  }
  return s;
}

}  // namespace

Result<CrsDefinition> crs_from_geotiff(const GeoTiffRecords& records, const std::string& where) {
  static Memo<CrsDefinition> memo;
  return memo.get(geotiff_source_text(records), [&]() -> Result<CrsDefinition> {
    Context ctx = new_context();
    if (!ctx) return internal_error(where + ": PROJ: cannot create a context");
    return geotiff_to_wkt2(ctx.get(), records, where);
  });
}

Result<std::string> wkt_to_wkt2(const std::string& wkt, const std::string& where) {
  static Memo<std::string> memo;
  return memo.get(wkt, [&]() -> Result<std::string> {
    Context ctx = new_context();
    if (!ctx) return internal_error(where + ": PROJ: cannot create a context");
    if (wkt.empty()) return invalid_argument(where + ": no CRS");
    RELIEF_ASSIGN_OR_RETURN(Pj crs, parse_wkt(ctx.get(), wkt, where));
    return as_wkt2(ctx.get(), crs.get(), where);
  });
}

Result<std::string> crs_to_wkt2(const std::string& text, const std::string& where) {
  static Memo<std::string> memo;
  return memo.get(text, [&]() -> Result<std::string> {
    Context ctx = new_context();
    if (!ctx) return internal_error(where + ": PROJ: cannot create a context");
    RELIEF_ASSIGN_OR_RETURN(Pj crs, parse_any(ctx.get(), text, where));
    return as_wkt2(ctx.get(), crs.get(), where);
  });
}

Result<CrsSummary> describe_crs(const std::string& text, const std::string& where) {
  static Memo<CrsSummary> memo;
  return memo.get(text, [&] { return describe_uncached(text, where); });
}

Result<bool> crs_equivalent(const std::string& a, const std::string& b) {
  static Memo<bool> memo;
  return memo.get(a + '\0' + b, [&]() -> Result<bool> {
    Context ctx = new_context();
    if (!ctx) return internal_error("PROJ: cannot create a context");
    RELIEF_ASSIGN_OR_RETURN(Pj pa, parse_any(ctx.get(), a, "CRS " + crs_label(a)));
    RELIEF_ASSIGN_OR_RETURN(Pj pb, parse_any(ctx.get(), b, "CRS " + crs_label(b)));
    return proj_is_equivalent_to_with_ctx(ctx.get(), pa.get(), pb.get(), PJ_COMP_EQUIVALENT) != 0;
  });
}

std::string crs_label(const std::string& text) {
  Result<CrsSummary> s = describe_crs(text, "CRS");
  if (!s.is_ok()) {
    std::string head = text.substr(0, 60);
    if (text.size() > 60) head += "...";
    return "\"" + head + "\"";
  }
  std::string label = "\"" + s->name + "\"";
  if (s->epsg) label += " (EPSG:" + std::to_string(*s->epsg) + ")";
  return label;
}

// ---- Conversions between CRSs

namespace {

// The horizontal CRS of `crs`: the first part of a compound CRS, else itself.
Pj horizontal_part(PJ_CONTEXT* ctx, const PJ* crs) {
  if (proj_get_type(crs) == PJ_TYPE_COMPOUND_CRS) return Pj(proj_crs_get_sub_crs(ctx, crs, 0));
  return Pj(proj_clone(ctx, crs));
}

}  // namespace

struct CrsTransform::Impl {
  Context ctx;
  Pj op;
};

CrsTransform::CrsTransform(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
CrsTransform::CrsTransform(CrsTransform&&) noexcept = default;
CrsTransform& CrsTransform::operator=(CrsTransform&&) noexcept = default;
CrsTransform::~CrsTransform() = default;

Result<CrsTransform> CrsTransform::create(const std::string& from, const std::string& to, const std::string& where) {
  auto impl = std::make_unique<Impl>();
  impl->ctx = new_context();
  PJ_CONTEXT* ctx = impl->ctx.get();
  if (!ctx) return internal_error(where + ": PROJ: cannot create a context");
  RELIEF_ASSIGN_OR_RETURN(Pj a, parse_any(ctx, from, where + ": CRS " + crs_label(from)));
  RELIEF_ASSIGN_OR_RETURN(Pj b, parse_any(ctx, to, where + ": CRS " + crs_label(to)));
  Pj ha = horizontal_part(ctx, a.get());
  Pj hb = horizontal_part(ctx, b.get());
  if (!ha || !hb) return format_error(where + ": the horizontal part of a CRS cannot be read: " + last_error(ctx));
  Pj op(proj_create_crs_to_crs_from_pj(ctx, ha.get(), hb.get(), nullptr, nullptr));
  if (!op) {
    return format_error(where + ": PROJ finds no conversion from " + crs_label(from) + " to " + crs_label(to) + ": " +
                        last_error(ctx));
  }
  impl->op.reset(proj_normalize_for_visualization(ctx, op.get()));
  if (!impl->op) return format_error(where + ": PROJ cannot put the conversion's axes in GIS order: " + last_error(ctx));
  return CrsTransform(std::move(impl));
}

bool CrsTransform::apply(double& x, double& y) const {
  if (!std::isfinite(x) || !std::isfinite(y)) return false;
  proj_errno_reset(impl_->op.get());
  const PJ_COORD out = proj_trans(impl_->op.get(), PJ_FWD, proj_coord(x, y, 0, 0));
  if (proj_errno(impl_->op.get()) != 0 || !std::isfinite(out.xy.x) || !std::isfinite(out.xy.y)) return false;
  x = out.xy.x;
  y = out.xy.y;
  return true;
}

}  // namespace relief
