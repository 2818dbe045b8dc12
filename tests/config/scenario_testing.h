#pragma once
// What the scenario-loading tests share: the one-line error of a scenario text, and a minimal
// simulation to add keys to.

#include <string>
#include <vector>

#include "common/config/config_error.h"
#include "common/config/scenario.h"

namespace mapmesh::testing {

// The ConfigError message of parsing text as "s.yaml", or "" when it loads.
inline std::string ErrorOf(const std::string& text, const std::vector<std::string>& sets = {}, int agents = 0) {
  try {
    std::vector<ConfigOverride> overrides;
    for (const auto& s : sets) overrides.push_back(ParseOverride(s));
    ParseScenario(text, "s.yaml", overrides, agents);
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

inline constexpr const char* kSimulation = R"(version: 1
world:
  landmarks:
    generator: {count: 10, area_m: [0, 0, 50, 50]}
robots:
  count: 2
)";

}  // namespace mapmesh::testing
