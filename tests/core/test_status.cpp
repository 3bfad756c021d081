#include <catch2/catch.hpp>

#include "relief/status.h"
#include "relief/types.h"

using namespace relief;

namespace {

Result<int> half(int v) {
  if (v % 2 != 0) return invalid_argument("odd value " + std::to_string(v));
  return v / 2;
}

Result<int> quarter(int v) {
  RELIEF_ASSIGN_OR_RETURN(int h, half(v));
  RELIEF_ASSIGN_OR_RETURN(int q, half(h));
  return q;
}

Status check_even(int v) {
  RELIEF_RETURN_IF_ERROR(half(v).status().is_ok() ? Status::ok() : half(v).status());
  return Status::ok();
}

}  // namespace

TEST_CASE("Status carries a stable code, name and message", "[core]") {
  const Status ok;
  CHECK(ok.is_ok());
  CHECK(ok.to_string() == "ok");
  const Status s = corrupt_data("blob damaged");
  CHECK_FALSE(s.is_ok());
  CHECK(s.code() == StatusCode::kCorruptData);
  CHECK(static_cast<int>(s.code()) == 4);  // codes are part of the API
  CHECK(s.to_string() == "corrupt-data: blob damaged");
  CHECK(s.with_context("chunk (1,2,3)").message() == "chunk (1,2,3): blob damaged");
  CHECK(std::string(status_code_name(StatusCode::kLimitExceeded)) == "limit-exceeded");
}

TEST_CASE("Result propagates values and errors through the macros", "[core]") {
  CHECK(*quarter(8) == 2);
  const auto r = quarter(6);
  REQUIRE_FALSE(r.is_ok());
  CHECK(r.status().message() == "odd value 3");
  CHECK(check_even(4).is_ok());
  CHECK(check_even(5).code() == StatusCode::kInvalidArgument);
}

TEST_CASE("PointCloud validation names the bad point", "[core]") {
  PointCloud c;
  c.positions = {{0, 0, 0}, {1, 2, 3}};
  CHECK(c.validate("x.ply").is_ok());
  c.colors = {{1, 2, 3}};
  CHECK(c.validate("x.ply").message().find("1 colours for 2 points") != std::string::npos);
  c.colors.clear();
  c.positions[1].z = std::numeric_limits<double>::infinity();
  const Status s = c.validate("x.ply");
  CHECK(s.code() == StatusCode::kInvalidArgument);
  CHECK(s.message().find("x.ply: point 1") == 0);
  c.positions[1].z = 3;
  c.intensities = {1.0f, std::numeric_limits<float>::quiet_NaN()};
  CHECK_FALSE(c.validate("x.ply").is_ok());
}

TEST_CASE("Box3d tracks bounds and diagonal", "[core]") {
  Box3d b;
  CHECK(b.empty());
  CHECK(b.diagonal() == 0);
  b.add({0, 0, 0});
  b.add({3, 4, 0});
  CHECK_FALSE(b.empty());
  CHECK(b.diagonal() == Approx(5.0));
}
