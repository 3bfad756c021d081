// Whether this build runs under AddressSanitizer (scripts/test.sh builds the
// suite a second time with ASan and UBSan, where code runs 10-25 times
// slower). Tests whose cost is repetition (every combination of attributes,
// several seeds, several shard counts) run a deterministic share of their
// rounds there, every code path still taken; the Release pass runs them all.
#pragma once

namespace relief::test {

#if defined(__SANITIZE_ADDRESS__)
inline constexpr bool kSanitized = true;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
inline constexpr bool kSanitized = true;
#else
inline constexpr bool kSanitized = false;
#endif
#else
inline constexpr bool kSanitized = false;
#endif

}  // namespace relief::test
