// Scenario loading's checks of keys: each bad case fails with one line naming the file, the
// line and the key.

#include <gtest/gtest.h>

#include "common/config/config_error.h"
#include "common/config/scenario.h"
#include "tests/config/scenario_testing.h"

namespace mapmesh {
namespace {

using testing::ErrorOf;
using testing::kSimulation;

TEST(ScenarioKeys, DuplicateKeysNameTheSecondOccurrence) {
  EXPECT_EQ(ErrorOf(std::string(kSimulation) + "radio: {range_m: 5}\nseed: 3\nradio: {range_m: 9}\n"),
            "s.yaml:9: radio: duplicate key (first given on line 7)");
  EXPECT_EQ(
      ErrorOf(std::string(kSimulation) + "  defaults:\n    sensor:\n      max_range_m: 5\n      max_range_m: 6\n"),
      "s.yaml:10: robots.defaults.sensor.max_range_m: duplicate key (first given on line 9)");
  EXPECT_EQ(ErrorOf("world: {landmarks: {generator: {count: 5, count: 6}}}\nrobots: {count: 1}\n"),
            "s.yaml:1: world.landmarks.generator.count: duplicate key (first given on line 1)");
  EXPECT_EQ(ErrorOf("world: {landmarks: {list: [[0, 0]]}}\nrobots:\n  list:\n    - {id: 1, id: 2}\n"),
            "s.yaml:4: robots.list[0].id: duplicate key (first given on line 4)");
  // An override sets the first occurrence; the duplicate is still the file's error, at its line.
  EXPECT_EQ(ErrorOf(std::string(kSimulation) + "seed: 1\nseed: 2\n", {"seed=4"}),
            "s.yaml:8: seed: duplicate key (first given on line 7)");
}

TEST(ScenarioKeys, KeysMustBePlainNames) {
  EXPECT_EQ(ErrorOf(std::string(kSimulation) + "? [a, b]\n: 1\n"),
            "s.yaml:7: (top level): a key must be a plain name, not a list, a mapping or null");
  EXPECT_EQ(ErrorOf(std::string(kSimulation) + "radio:\n  {a: 1}: 2\n"),
            "s.yaml:8: radio: a key must be a plain name, not a list, a mapping or null");
  EXPECT_EQ(ErrorOf(std::string(kSimulation) + "radio: {~: 2}\n"),
            "s.yaml:7: radio: a key must be a plain name, not a list, a mapping or null");
}

// A quoted key or value may hold control characters; the message shows them escaped, on one
// line (found by the scenario fuzz target: a NUL and a newline in an unknown key).
TEST(ScenarioKeys, ControlCharactersInKeysAndValuesAreEscaped) {
  EXPECT_EQ(ErrorOf(std::string(kSimulation) + "  defaults:\n    \"sen\\nso\\0r\": 1\n"),
            "s.yaml:8: robots.defaults.sen\\nso\\x00r: unknown key");
  EXPECT_EQ(ErrorOf(std::string(kSimulation) + "seed: \"1\\r\\t2\"\n"),
            "s.yaml:7: seed: expected a non-negative integer, got '1\\r\\t2'");
}

}  // namespace
}  // namespace mapmesh
