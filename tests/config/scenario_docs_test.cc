// docs/SCENARIOS.md against the loader: every key the docs list is one the loader reads, and
// every key the loader reads is in the docs. The loader's side comes from parsing the shipped
// scenarios and variants that take every branch (each generator, path type, source, preset),
// recording the key paths it asked for.

#include <gtest/gtest.h>

#include <fstream>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "common/config/scenario.h"
#include "tests/config/scenario_testing.h"

namespace mapmesh {
namespace {

using testing::TempDirTest;

std::string ReadText(const std::filesystem::path& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

// The backticked names in a table row's first cell (cells split at unescaped '|').
std::vector<std::string> FirstCellNames(const std::string& row) {
  std::vector<std::string> cells(1);
  for (std::size_t i = 0; i < row.size(); ++i) {
    if (row[i] == '\\' && i + 1 < row.size()) {
      cells.back() += row[++i];
    } else if (row[i] == '|') {
      cells.emplace_back();
    } else {
      cells.back() += row[i];
    }
  }
  std::vector<std::string> names;
  if (cells.size() < 2) return names;
  const std::string& cell = cells[1];
  for (std::size_t open = cell.find('`'); open != std::string::npos; open = cell.find('`', open + 1)) {
    const std::size_t close = cell.find('`', open + 1);
    if (close == std::string::npos) break;
    names.push_back(cell.substr(open + 1, close - open - 1));
    open = close;
  }
  return names;
}

// The full key paths docs/SCENARIOS.md documents, up to its list of shipped scenarios. A row
// may name several keys: a later one with a dot is given in full, one without (or starting
// with a dot) is a sibling of the first. The robots section's `motion`, `sensor` and `path`
// tables apply to both robots.defaults and robots.list[]. A list key `x[]` is `x`.
std::set<std::string> DocumentedKeys() {
  std::ifstream in(std::string(MAPMESH_SOURCE_DIR) + "/docs/SCENARIOS.md");
  EXPECT_TRUE(in.good());
  std::set<std::string> keys;
  std::vector<std::string> prefixes;
  bool in_keys = false, in_robots = false;
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("## Keys", 0) == 0) in_keys = true;
    if (line.rfind("## Shipped scenarios", 0) == 0) break;
    if (!in_keys) continue;
    if (line.rfind("### ", 0) == 0) {
      const std::size_t open = line.find('`'), close = line.rfind('`');
      const std::string section = open == std::string::npos ? "" : line.substr(open + 1, close - open - 1);
      prefixes = {section.empty() ? "" : section + "."};
      in_robots = section == "robots";
      continue;
    }
    if (in_robots) {
      for (const char* sub : {"motion", "sensor", "path"}) {
        if (line.rfind(std::string("`") + sub + "`", 0) == 0) {
          prefixes = {std::string("robots.defaults.") + sub + ".", std::string("robots.list[].") + sub + "."};
        }
      }
    }
    if (line.rfind("| `", 0) != 0) continue;
    const std::vector<std::string> names = FirstCellNames(line);
    EXPECT_FALSE(names.empty()) << line;
    if (names.empty()) continue;
    const std::size_t dot = names[0].rfind('.');
    const std::string parent = dot == std::string::npos ? "" : names[0].substr(0, dot + 1);
    for (std::size_t i = 0; i < names.size(); ++i) {
      std::string key = names[i];
      if (i > 0 && key.front() == '.') {
        key = parent + key.substr(1);
      } else if (i > 0 && key.find('.') == std::string::npos) {
        key = parent + key;
      }
      if (key.size() > 2 && key.compare(key.size() - 2, 2, "[]") == 0) key.resize(key.size() - 2);
      for (const std::string& prefix : prefixes) keys.insert(prefix + key);
    }
  }
  return keys;
}

class ScenarioDocs : public TempDirTest {
 protected:
  // Parses text as a scenario file in the test's folder, recording the keys read.
  void Parse(const std::string& text, const std::string& name = "s.yaml") {
    const std::filesystem::path path = dir_ / name;
    std::ofstream(path) << text;
    SCOPED_TRACE(text);
    EXPECT_NO_THROW(ParseScenario(text, path.string(), {}, 0, &read_));
  }
  std::set<std::string> read_;
};

TEST_F(ScenarioDocs, EveryDocumentedKeyIsReadAndEveryKeyReadIsDocumented) {
  // The shipped scenarios (the dataset ones parse without their data).
  for (const auto& entry : std::filesystem::directory_iterator(std::string(MAPMESH_SOURCE_DIR) + "/scenarios")) {
    if (entry.path().extension() != ".yaml") continue;
    SCOPED_TRACE(entry.path().string());
    EXPECT_NO_THROW(ParseScenario(ReadText(entry.path()), entry.path().string(), {}, 0, &read_));
  }
  // Every landmark source and generator, and a victoria_park and a mrclam source with their keys.
  std::ofstream(dir_ / "trees.csv") << "x,y\n1,2\n3,4\n";
  Parse("version: 1\nworld: {landmarks: {csv: trees.csv}}\nrobots: {count: 1}\n");
  Parse("version: 1\nworld: {landmarks: {list: [[1, 2], [3, 4]]}}\nrobots: {count: 1}\n");
  for (const char* generator : {"uniform", "park", "disc"}) {
    Parse(std::string("version: 1\nworld: {landmarks: {generator: {type: ") + generator + "}}}\nrobots: {count: 1}\n");
  }
  Parse("version: 1\nsource: {type: mrclam, robots: [1, 2], odometry_delay_s: 0.25}\n");
  Parse("version: 1\nsource: {type: victoria_park, virtual_robots: 3, overlap_s: 30}\n");
  // Every path type, in the defaults and in a listed robot; each preset, in both places too.
  for (const char* type : {"waypoints", "random", "circle", "lawnmower", "park"}) {
    const std::string extra = std::string(type) == "waypoints" ? ", points: [[1, 1], [5, 5]]"
                              : std::string(type) == "random" || std::string(type) == "lawnmower"
                                  ? ", area_m: [0, 0, 20, 20]"
                                  : "";
    const std::string path = std::string("{type: ") + type + extra + "}";
    Parse("version: 1\nworld: {landmarks: {generator: {type: park}}}\nrobots:\n  defaults: {path: " + path +
          "}\n  list: [{id: 1, path: " + path + "}]\n");
  }
  // Every kind of fault.
  Parse("version: 1\nworld: {landmarks: {generator: {count: 10}}}\nrobots: {count: 3}\nfaults:\n"
        "  kill: [{id: 3, t: 20}]\n  restart: [{id: 3, t: 35}]\n  pause: [{id: 2, t: 30, seconds: 3}]\n"
        "  inject: {cases: all, period_s: 0.5}\n");
  for (const char* preset : {"thesis", "downs"}) {
    Parse(std::string("version: 1\nworld: {landmarks: {generator: {count: 10}}}\nrobots:\n  defaults: {preset: ") +
          preset + "}\n  list: [{id: 1, preset: " + preset + ", start: [0, 0, 0]}]\n");
  }

  const std::set<std::string> documented = DocumentedKeys();
  ASSERT_GT(documented.size(), 100u);
  ASSERT_GT(read_.size(), 100u);
  for (const std::string& key : read_) EXPECT_TRUE(documented.count(key)) << key << " is read but not documented";
  for (const std::string& key : documented) {
    // A mapping the docs name as a whole (robots.defaults.motion) counts as read through its keys.
    const auto next = read_.lower_bound(key + ".");
    const bool through_keys = next != read_.end() && next->rfind(key + ".", 0) == 0;
    EXPECT_TRUE(read_.count(key) || through_keys) << key << " is documented but never read";
  }
}

// The docs' side of the check reads every kind of row: plain, several keys in one, the robots'
// sub-tables for both places, lists; and nothing below the key tables.
TEST(ScenarioDocsCheck, ReadsEveryKindOfKeyRow) {
  const std::set<std::string> documented = DocumentedKeys();
  EXPECT_TRUE(documented.count("agent.fusion"));
  EXPECT_TRUE(documented.count("robots.list[].motion.speed_mps"));
  EXPECT_TRUE(documented.count("robots.defaults.path.spacing_m"));
  EXPECT_TRUE(documented.count("world.landmarks.generator.radius_m"));
  EXPECT_TRUE(documented.count("robots.list"));
  EXPECT_FALSE(documented.count("agent.no_such_key"));
  EXPECT_FALSE(documented.count("cluttered.yaml"));  // the shipped-scenarios table is not keys
}

}  // namespace
}  // namespace mapmesh
