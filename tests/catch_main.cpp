// Catch2 v2 main, compiled once. Exits with kSkipReturnCode when every test
// case it ran was skipped for want of optional data (support/skip.h).
#define CATCH_CONFIG_RUNNER
#include <catch2/catch.hpp>

#include "support/skip.h"

namespace {

using relief::test::skip_tally;

struct SkipListener : Catch::TestEventListenerBase {
  using TestEventListenerBase::TestEventListenerBase;
  void testCaseStarting(Catch::TestCaseInfo const&) override {
    skip_tally().current_absent = false;
    skip_tally().current_present = false;
  }
  void testCaseEnded(Catch::TestCaseStats const&) override {
    ++skip_tally().cases_run;
    if (skip_tally().current_absent && !skip_tally().current_present) ++skip_tally().cases_skipped;
  }
};

}  // namespace

CATCH_REGISTER_LISTENER(SkipListener)

int main(int argc, char* argv[]) {
  const int result = Catch::Session().run(argc, argv);
  const auto& t = skip_tally();
  if (result == 0 && t.cases_run > 0 && t.cases_skipped == t.cases_run) return relief::test::kSkipReturnCode;
  return result;
}
