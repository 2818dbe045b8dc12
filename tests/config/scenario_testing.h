#pragma once
// What the scenario-loading tests share: the one-line error of a scenario text, a minimal
// simulation to add keys to, and a fixture with its own temporary folder.

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <string>
#include <vector>

#include "common/config/config_error.h"
#include "common/config/scenario.h"

namespace mapmesh::testing {

// A fixture owning a fresh folder per test (named after the test and the process), removed after.
class TempDirTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() /
           ("mapmesh_" + std::string(::testing::UnitTest::GetInstance()->current_test_suite()->name()) + "_" +
            std::to_string(::getpid()) + "_" + ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::filesystem::path dir_;
};

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
