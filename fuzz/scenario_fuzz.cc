// libFuzzer target for the scenario parser (common/config/scenario.h): ParseScenario on
// arbitrary YAML. Bad input is a ConfigError whose message is one line naming the file;
// anything else escaping (YAML exceptions, std::bad_alloc, std::out_of_range, ...) is a finding.
//
// The input is the scenario text; comment lines "#--set key.path=value" add overrides (at most
// 8) and a line "#--agents N" sets the robot count (0-64, as --agents would), so that the
// seeds stay valid scenarios. The file is named inside a temporary directory that holds only
// two landmark CSV files (landmarks.csv, bad.csv), so that relative landmarks.csv paths read
// only those; inputs that could name a file elsewhere are skipped, which keeps the target
// hermetic (it reads no other file, and no dataset: ParseScenario does not read datasets).

#include <unistd.h>

#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include <yaml-cpp/yaml.h>

#include "common/config/config_error.h"
#include "common/config/scenario.h"
#include "fuzz/fuzz_check.h"

namespace mapmesh {
namespace {

constexpr std::size_t kMaxOverrides = 8;
constexpr int kMaxAgents = 64;

// The directory the scenario "lives" in: $TMPDIR/mapmesh-fuzz-scenario-<uid>, holding only
// the two CSV files. It is the same for every run, so that messages and reproducers are too.
std::string& File() {
  static std::string file;
  return file;
}

// Writes path atomically (a parallel job may be reading it) unless it already holds text.
void WriteOnce(const std::filesystem::path& path, const std::string& text) {
  std::ifstream in(path, std::ios::binary);
  const std::string held((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in && held == text) return;
  const std::filesystem::path tmp = path.string() + "." + std::to_string(getpid());
  std::ofstream(tmp, std::ios::binary) << text;
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) std::filesystem::remove(tmp, ec);
}

// Makes the directory and its two CSV files (the same ones each time).
void MakeDir() {
  const char* tmp = std::getenv("TMPDIR");
  const std::filesystem::path dir = std::filesystem::path(tmp != nullptr && *tmp != '\0' ? tmp : "/tmp") /
                                    ("mapmesh-fuzz-scenario-" + std::to_string(getuid()));
  std::filesystem::create_directories(dir);
  WriteOnce(dir / "landmarks.csv", "x,y\n0,0\n10.5,-3\n# a comment\n\n 20 , 20\n");
  WriteOnce(dir / "bad.csv", "1,2\nnot a row\n");
  File() = (dir / "fuzz.yaml").string();
}

// True when some "csv" key in the tree holds a scalar with a '/', within a bounded walk
// (false when the text does not parse: ParseScenario then refuses it before any file).
bool CsvMayLeaveDir(const std::string& text) {
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::Exception&) {
    return false;
  }
  std::vector<std::pair<YAML::Node, bool>> stack{{root, false}};  // node, below a "csv" key
  for (int budget = 100000; !stack.empty(); --budget) {
    if (budget == 0) return true;  // too large (or aliased) to be sure: skip it
    auto [n, in_csv] = stack.back();
    stack.pop_back();
    if (n.IsScalar()) {
      if (in_csv && n.Scalar().find('/') != std::string::npos) return true;
    } else if (n.IsSequence()) {
      for (const YAML::Node& e : n) stack.push_back({e, in_csv});
    } else if (n.IsMap()) {
      for (const auto& kv : n) {
        const bool csv_key = kv.first.IsScalar() && kv.first.Scalar() == "csv";
        stack.push_back({kv.first, in_csv});
        stack.push_back({kv.second, in_csv || csv_key});
      }
    }
  }
  return false;
}

// Reads the "#--set" and "#--agents" lines; false when the input should be skipped.
bool ReadDirectives(const std::string& text, std::vector<ConfigOverride>* overrides, int* agents) {
  std::size_t begin = 0;
  while (begin < text.size()) {
    std::size_t end = text.find('\n', begin);
    if (end == std::string::npos) end = text.size();
    const std::string_view line(text.data() + begin, end - begin);
    begin = end + 1;
    if (line.starts_with("#--set ")) {
      const std::string set(line.substr(7));
      const std::size_t eq = set.find('=');
      if (eq == std::string::npos || eq == 0 || overrides->size() == kMaxOverrides) continue;
      // A value that could spell a path (a '/' or an escape) might point landmarks.csv away.
      if (set.find_first_of("/\\", eq) != std::string::npos) return false;
      try {
        overrides->push_back(ParseOverride(set));
      } catch (const ConfigError& e) {
        // An empty value is refused by ParseOverride itself, in one line naming the option.
        const std::string what = e.what();
        MAPMESH_FUZZ_CHECK_SHOWING(what.starts_with("--set "), what.c_str());
        MAPMESH_FUZZ_CHECK_SHOWING(what.find_first_of("\n\r") == std::string::npos, what.c_str());
        return false;
      }
    } else if (line.starts_with("#--agents ")) {
      const std::string n(line.substr(10));
      char* stop = nullptr;
      const long v = std::strtol(n.c_str(), &stop, 10);
      if (stop != n.c_str() && v >= 0 && v <= kMaxAgents) *agents = static_cast<int>(v);
    }
  }
  return true;
}

int FuzzOne(const std::string& text) {
  std::vector<ConfigOverride> overrides;
  int agents = 0;
  if (!ReadDirectives(text, &overrides, &agents)) return -1;
  if ((text.find("csv") != std::string::npos || text.find('\\') != std::string::npos) && CsvMayLeaveDir(text)) {
    return -1;
  }
  try {
    const Scenario sc = ParseScenario(text, File(), overrides, agents);
    MAPMESH_FUZZ_CHECK(sc.version == 1);
    MAPMESH_FUZZ_CHECK(sc.path == File());
    MAPMESH_FUZZ_CHECK(!sc.robots.empty());
    MAPMESH_FUZZ_CHECK(agents == 0 || sc.robots.size() == static_cast<std::size_t>(agents));
    std::set<RobotId> ids;
    for (const RobotSpec& r : sc.robots) {
      MAPMESH_FUZZ_CHECK(r.id >= 1);
      MAPMESH_FUZZ_CHECK(ids.insert(r.id).second);
    }
  } catch (const ConfigError& e) {
    const std::string what = e.what();
    MAPMESH_FUZZ_CHECK_SHOWING(what.starts_with(File() + ":"), what.c_str());
    MAPMESH_FUZZ_CHECK_SHOWING(what.find_first_of("\n\r") == std::string::npos, what.c_str());
  }
  return 0;
}

}  // namespace
}  // namespace mapmesh

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  mapmesh::MakeDir();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  return mapmesh::FuzzOne(std::string(reinterpret_cast<const char*>(data), size));
}
