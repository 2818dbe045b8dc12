#pragma once
// Always-on precondition checks. A failed check is a programming error: it prints the
// condition and location to stderr and aborts. Expected failures (bad input, no alignment)
// are return values, never checks.

#include <cstdio>
#include <cstdlib>

namespace mapmesh::detail {
[[noreturn]] inline void CheckFailed(const char* cond, const char* file, int line, const char* msg) {
  std::fprintf(stderr, "%s:%d: check failed: %s%s%s\n", file, line, cond, msg[0] ? ": " : "", msg);
  std::abort();
}
}  // namespace mapmesh::detail

// MAPMESH_CHECK(cond) or MAPMESH_CHECK(cond, "message").
#define MAPMESH_CHECK(cond, ...)                                                            \
  do {                                                                                      \
    if (!(cond)) ::mapmesh::detail::CheckFailed(#cond, __FILE__, __LINE__, "" __VA_ARGS__); \
  } while (0)
