#pragma once
// The fuzz targets' contract check: a violated property prints what failed and aborts, so
// that libFuzzer reports it as a crash with the input that caused it.

#include <cstdio>
#include <cstdlib>

#define MAPMESH_FUZZ_CHECK(condition) MAPMESH_FUZZ_CHECK_SHOWING(condition, "")

// The same, also printing `shown` (a C string: the message or value under test).
#define MAPMESH_FUZZ_CHECK_SHOWING(condition, shown)                                             \
  do {                                                                                           \
    if (!(condition)) {                                                                          \
      std::fprintf(stderr, "%s:%d: contract violated: %s\n%s%s", __FILE__, __LINE__, #condition, \
                   static_cast<const char*>(shown), *(shown) != '\0' ? "\n" : "");               \
      std::abort();                                                                              \
    }                                                                                            \
  } while (false)
