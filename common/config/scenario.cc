#include "common/config/scenario.h"

#include <yaml-cpp/eventhandler.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <set>
#include <sstream>

#include "common/config/scenario_sections.h"
#include "common/config/yaml_reader.h"
#include "common/types/scenario_limits.h"

namespace mapmesh {
namespace {

// Counts the document's values as the parser streams them, without building it; throws
// ConfigError at the first value past limits::kMaxScenarioValues. Syntax errors are left to
// YAML::Load, which reports them.
class ValueCounter : public YAML::EventHandler {
 public:
  explicit ValueCounter(const std::string& file) : file_(file) {}
  void OnDocumentStart(const YAML::Mark&) override {}
  void OnDocumentEnd() override {}
  void OnNull(const YAML::Mark& m, YAML::anchor_t) override { Count(m); }
  void OnAlias(const YAML::Mark& m, YAML::anchor_t) override { Count(m); }
  void OnScalar(const YAML::Mark& m, const std::string&, YAML::anchor_t, const std::string&) override { Count(m); }
  void OnSequenceStart(const YAML::Mark& m, const std::string&, YAML::anchor_t, YAML::EmitterStyle::value) override {
    Count(m);
  }
  void OnSequenceEnd() override {}
  void OnMapStart(const YAML::Mark& m, const std::string&, YAML::anchor_t, YAML::EmitterStyle::value) override {
    Count(m);
  }
  void OnMapEnd() override {}

 private:
  void Count(const YAML::Mark& m) {
    if (++values_ <= limits::kMaxScenarioValues) return;
    throw ConfigError(file_ + ":" + std::to_string(m.line + 1) + ": (top level): more than " +
                      std::to_string(limits::kMaxScenarioValues) +
                      " values in the file (a scenario holds hundreds; a large landmark map goes in "
                      "world.landmarks.csv)");
  }
  const std::string& file_;
  std::size_t values_ = 0;
};

void CheckValueCount(const std::string& yaml_text, const std::string& file) {
  std::istringstream in(yaml_text);
  YAML::Parser parser(in);
  ValueCounter counter(file);
  try {
    while (parser.HandleNextDocument(counter)) {
    }
  } catch (const YAML::ParserException&) {
    // YAML::Load reports it, with its line
  }
}

using scenario_internal::ReadAgent;
using scenario_internal::ReadFaults;
using scenario_internal::ReadFeeder;
using scenario_internal::ReadMotion;
using scenario_internal::ReadPath;
using scenario_internal::ReadPreset;
using scenario_internal::ReadRadio;
using scenario_internal::ReadSensor;
using scenario_internal::ReadSource;
using scenario_internal::ReadWorld;

// Sets key_path (dots and [i] indices) in root to the YAML value, creating maps as needed.
void ApplyOverride(YAML::Node root, const ConfigOverride& o, const std::string& file) {
  YAML::Node value;
  try {
    value = YAML::Load(o.value);
  } catch (const YAML::Exception& e) {
    throw ConfigError(file + ": --set " + o.key_path + ": cannot parse value '" + o.value + "'");
  }
  // An empty (or null) value would leave the key at its default without a word.
  if (!value.IsDefined() || value.IsNull()) {
    throw ConfigError(file + ": --set " + o.key_path + ": empty value (give key.path=VALUE)");
  }
  YAML::Node cur;
  cur.reset(root);
  std::stringstream ss(o.key_path);
  std::string seg;
  std::vector<std::string> segs;
  while (std::getline(ss, seg, '.')) segs.push_back(seg);
  for (std::size_t i = 0; i < segs.size(); ++i) {
    std::string name = segs[i];
    std::optional<std::size_t> index;
    if (auto lb = name.find('['); lb != std::string::npos && name.back() == ']') {
      try {
        index = std::stoul(name.substr(lb + 1, name.size() - lb - 2));
      } catch (const std::exception&) {
        throw ConfigError(file + ": --set " + o.key_path + ": bad index in '" + name + "'");
      }
      name = name.substr(0, lb);
    }
    const bool last = i + 1 == segs.size();
    if (cur.IsDefined() && !cur.IsNull() && !cur.IsMap()) {
      throw ConfigError(file + ": --set " + o.key_path + ": '" + name + "' is not inside a mapping");
    }
    YAML::Node next = cur[name];
    if (index) {
      if (!next.IsSequence() || *index >= next.size()) {
        throw ConfigError(file + ": --set " + o.key_path + ": no element " + std::to_string(*index) + " in '" + name +
                          "'");
      }
      YAML::Node elem;
      elem.reset(next[*index]);
      if (last) {
        next[*index] = value;
      } else {
        cur.reset(elem);
      }
      continue;
    }
    if (last) {
      cur[name] = value;
    } else {
      if (!next.IsDefined() || next.IsNull()) cur[name] = YAML::Node(YAML::NodeType::Map);
      YAML::Node child;
      child.reset(cur[name]);
      cur.reset(child);
    }
  }
}

std::vector<Eigen::Vector2d> RandomPoints(int count, const Rect& area, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> ux(area.xmin, area.xmax), uy(area.ymin, area.ymax);
  std::vector<Eigen::Vector2d> pts;
  for (int i = 0; i < count; ++i) {
    const double x = ux(rng);
    pts.emplace_back(x, uy(rng));
  }
  return pts;
}

// Fills in the waypoints (and, unless given, the start pose) of a robot's path.
void ResolvePath(RobotSpec& spec, const Rect& bounds, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> ux(bounds.xmin, bounds.xmax), uy(bounds.ymin, bounds.ymax),
      uth(-std::numbers::pi, std::numbers::pi);
  const double x = ux(rng), y = uy(rng), th = uth(rng);
  const Pose2 drawn{x, y, th};
  PathOptions& path = spec.path;
  const auto random_points = RandomPoints(path.count, path.area_m.value_or(bounds), rng);
  Pose2 start = drawn;
  if (path.type == PathType::kRandom) {
    path.points = random_points;
  } else if (path.type == PathType::kCircle) {
    path.points = CircleWaypoints(path, &start);
  } else if (path.type == PathType::kLawnmower) {
    path.points = LawnmowerWaypoints(path.area_m.value_or(bounds), path.spacing_m);
    const Eigen::Vector2d d = path.points[1] - path.points[0];
    start = {path.points[0].x(), path.points[0].y(), std::atan2(d.y(), d.x())};
  }
  // (park paths are resolved by the simulator, which generates the park.)
  if (!spec.start_given) spec.start = start;
}

}  // namespace

const RobotSpec* Scenario::FindRobot(RobotId id) const {
  for (const auto& r : robots) {
    if (r.id == id) return &r;
  }
  return nullptr;
}

MotionOptions MotionOptions::DownsDefaults() {
  MotionOptions m;
  m.speed_mps = 1.0;  // Downs 4.2: up to 1 m/s
  m.max_turn_rate_dps = 90.0;
  m.steering = Steering::kSmooth;  // Downs turns towards the waypoint, then drives
  m.sigma_v_mps = 0.01;
  m.sigma_w_radps = 0.01;
  return m;
}

SensorOptions SensorOptions::DownsDefaults() {
  SensorOptions s;
  s.max_range_m = 10.0;  // Downs 4.2: 10 m
  s.fov_deg = 45.0;      // pi / 4 arc
  s.sigma_range_m = 0.01;
  s.sigma_bearing_deg = 0.573;  // 0.01 rad
  s.scan_every_steps = 10;      // one observation a second at the 0.1 s step
  return s;
}

MotionModel MotionModelFor(const MotionOptions& motion) {
  MotionModel m;
  m.kind = motion.model;
  m.ackermann = motion.ackermann;
  return m;
}

std::vector<Eigen::Vector2d> CircleWaypoints(const PathOptions& path, Pose2* start) {
  const double dir = path.clockwise ? -1.0 : 1.0;
  const double a0 = DegToRad(path.start_angle_deg);
  std::vector<Eigen::Vector2d> pts;
  for (int i = 1; i <= path.count; ++i) {
    const double a = a0 + dir * 2.0 * std::numbers::pi * i / path.count;
    pts.emplace_back(path.center_m.x() + path.radius_m * std::cos(a), path.center_m.y() + path.radius_m * std::sin(a));
  }
  if (start) {
    *start = {path.center_m.x() + path.radius_m * std::cos(a0), path.center_m.y() + path.radius_m * std::sin(a0),
              WrapAngle(a0 + dir * std::numbers::pi / 2)};
  }
  return pts;
}

std::vector<Eigen::Vector2d> LawnmowerWaypoints(const Rect& area, double spacing_m) {
  std::vector<Eigen::Vector2d> pts;
  const int lanes = std::max(1, static_cast<int>(std::floor(area.Height() / spacing_m)) + 1);
  for (int i = 0; i < lanes; ++i) {
    const double y = std::min(area.ymax, area.ymin + i * spacing_m);
    const bool left_to_right = i % 2 == 0;
    pts.emplace_back(left_to_right ? area.xmin : area.xmax, y);
    pts.emplace_back(left_to_right ? area.xmax : area.xmin, y);
  }
  return pts;
}

ConfigOverride ParseOverride(const std::string& text) {
  const auto eq = text.find('=');
  if (eq == std::string::npos || eq == 0) {
    throw ConfigError("--set " + text + ": expected key.path=value");
  }
  if (text.find_first_not_of(" \t", eq + 1) == std::string::npos) {
    throw ConfigError("--set " + text.substr(0, eq) + ": empty value (give key.path=VALUE)");
  }
  return {text.substr(0, eq), text.substr(eq + 1)};
}

Scenario ParseScenario(const std::string& yaml_text, const std::string& file,
                       const std::vector<ConfigOverride>& overrides, int agents, std::set<std::string>* keys_read) {
  auto source = std::make_shared<YamlSource>();
  source->file = file;
  source->keys_read = keys_read;
  CheckValueCount(yaml_text, file);
  YAML::Node root;
  try {
    root = YAML::Load(yaml_text);
  } catch (const YAML::ParserException& e) {
    throw ConfigError(file + ":" + std::to_string(e.mark.line + 1) + ": (syntax): " + e.msg);
  }
  if (!root || root.IsNull()) root = YAML::Node(YAML::NodeType::Map);
  if (!root.IsMap()) throw ConfigError(file + ":1: (top level): expected a mapping of keys");
  for (const auto& o : overrides) {
    ApplyOverride(root, o, file);
    source->overridden.insert(o.key_path);
  }

  if (agents < 0 || agents > limits::kMaxRobots) {
    throw ConfigError(file + ": --agents " + std::to_string(agents) + ": must be in [0, " +
                      std::to_string(limits::kMaxRobots) + "] (0: the scenario's robots)");
  }
  Scenario sc;
  source->resolved = &sc.resolved;
  YamlReader top(root, "", source);
  sc.path = file;
  top.Get("version", sc.version);
  if (sc.version != 1) top.Fail("version", "unsupported scenario version (this build reads 1)");
  top.Get("name", sc.name);
  if (sc.name.empty()) sc.name = std::filesystem::path(file).stem().string();
  top.Get("description", sc.description);
  top.Get("seed", sc.seed);
  sc.source = ReadSource(top.Child("source"));
  const bool dataset = sc.source.IsDataset();
  sc.duration_given = top.Has("duration_s");
  if (dataset) sc.duration_s = 0.0;  // the whole dataset, unless given
  if (sc.duration_given || !dataset) top.GetPositiveUpTo("duration_s", sc.duration_s, limits::kMaxDurationS);

  const std::string dir = std::filesystem::path(file).parent_path().string();
  sc.world = ReadWorld(top.Child("world"), dir.empty() ? "." : dir, dataset);
  sc.radio = ReadRadio(top.Child("radio"));
  sc.agent = ReadAgent(top.Child("agent"));
  sc.feeder = ReadFeeder(top.Child("feeder"));
  sc.faults = ReadFaults(top.Child("faults"), dataset && !sc.duration_given ? 0.0 : sc.duration_s);
  if (!dataset && sc.duration_s / sc.world.control_period_s > limits::kMaxSimulationSteps) {
    top.Fail("duration_s", "the run would take " +
                               std::to_string(std::llround(sc.duration_s / sc.world.control_period_s)) +
                               " steps of world.control_period_s (at most " +
                               std::to_string(static_cast<long long>(limits::kMaxSimulationSteps)) + ")");
  }
  if (sc.agent.max_stamp_jump_s < 2.0 * sc.feeder.lockstep_window_s) {
    // Lockstep publishes scans up to a window ahead of the odometry that covers them.
    top.Child("agent").Fail("max_stamp_jump_s", "must be at least twice feeder.lockstep_window_s");
  }

  // Robots: defaults, then the listed ones (each overriding defaults key by key).
  YamlReader robots = top.Child("robots");
  RobotSpec defaults;
  int count = -1;
  robots.Get("count", count);
  if (robots.Has("count")) {
    if (dataset) robots.Fail("count", "a dataset scenario's robots come from the dataset (use --agents)");
    robots.CheckRange("count", count, 0, limits::kMaxRobots);
  }
  {
    YamlReader d = robots.Child("defaults");
    ReadPreset(d, defaults);
    ReadMotion(d.Child("motion"), defaults.motion);
    ReadSensor(d.Child("sensor"), defaults.sensor);
    ReadPath(d.Child("path"), defaults.path, sc.world.bounds_m);
    d.Finish();
  }
  std::vector<RobotSpec> listed;
  std::set<RobotId> ids;
  robots.ForEach("list", limits::kMaxRobots, [&](const YAML::Node& node, const std::string& path) {
    YamlReader r = robots.Element(node, path);
    RobotSpec spec = defaults;
    int id = 0;
    r.Get("id", id);
    if (!r.Has("id")) r.FailAt(node, path + ".id", "missing required key");
    if (id < 1) r.Fail("id", "must be a positive integer");
    r.CheckRange("id", id, 1, limits::kMaxRobotId);
    if (!ids.insert(static_cast<RobotId>(id)).second) r.Fail("id", "duplicate robot id");
    spec.id = static_cast<RobotId>(id);
    std::vector<double> start;
    r.GetVector("start", start, 3);
    if (!start.empty()) {
      if (dataset) r.Fail("start", "a dataset robot starts where the data says");
      scenario_internal::CheckCoordinates(r, "start", {start[0], start[1]});
      if (!(std::abs(start[2]) <= limits::kMaxAngleDeg)) {
        r.Fail("start", "the heading must be within +-" + FormatNumber(limits::kMaxAngleDeg) + " degrees (got " +
                            FormatNumber(start[2]) + ")");
      }
      spec.start = {start[0], start[1], WrapAngle(DegToRad(start[2]))};
      spec.start_given = true;
    }
    ReadPreset(r, spec);
    ReadMotion(r.Child("motion"), spec.motion);
    ReadSensor(r.Child("sensor"), spec.sensor);
    ReadPath(r.Child("path"), spec.path, sc.world.bounds_m);
    r.Finish();
    listed.push_back(spec);
  });
  robots.Finish();
  top.Finish();

  if (dataset) {
    // The dataset decides the robots; listed ones only adjust their settings.
    std::vector<RobotId> dataset_ids = sc.source.robots;
    if (sc.source.type == SourceType::kVictoriaPark) {
      if (agents > 0) sc.source.virtual_robots = agents;
      dataset_ids.clear();
      for (int k = 1; k <= sc.source.virtual_robots; ++k) dataset_ids.push_back(static_cast<RobotId>(k));
    } else if (agents > 0) {
      if (agents > static_cast<int>(dataset_ids.size())) {
        throw ConfigError(file + ": --agents " + std::to_string(agents) + ": the dataset has only " +
                          std::to_string(dataset_ids.size()) + " robots");
      }
      dataset_ids.resize(agents);
    }
    for (RobotId id : dataset_ids) {
      RobotSpec spec = defaults;
      for (const RobotSpec& l : listed) {
        if (l.id == id) spec = l;
      }
      spec.id = id;
      sc.robots.push_back(spec);
    }
    for (const RobotSpec& l : listed) {
      if (!sc.FindRobot(l.id)) {
        throw ConfigError(file + ": robots.list: robot " + std::to_string(l.id) + " is not in the dataset run");
      }
    }
    return sc;
  }

  int wanted = agents > 0 ? agents : (count >= 0 ? count : static_cast<int>(listed.size()));
  if (wanted == 0 && agents <= 0) {
    throw ConfigError(file + ":1: robots: the scenario has no robots (give robots.list or robots.count)");
  }

  // Resolve the run's robots: the first listed ones, then generated ones. Each robot draws
  // from its own generator, seeded from the scenario seed and its position in the list, so
  // robot k is the same whatever N is and whatever the other robots are.
  RobotId next_id = ids.empty() ? 1 : *ids.rbegin() + 1;
  // Every process of a run loads every robot's path: their waypoints together are bounded
  // (1024 robots of 10000 waypoints each would take 330 MB in each process).
  std::size_t total_waypoints = 0;
  for (int i = 0; i < wanted; ++i) {
    RobotSpec spec;
    if (i < static_cast<int>(listed.size())) {
      spec = listed[i];
    } else {
      spec = defaults;
      spec.id = next_id++;
      spec.path.index = i;  // generated robots take the park's footpaths in turn
    }
    if (spec.motion.model != MotionModel::Kind::kUnicycle) {
      throw ConfigError(file + ": robots: robot " + std::to_string(spec.id) + ": motion.model " +
                        std::string(NameOf(kMotionModels, spec.motion.model)) + " is only for dataset replays");
    }
    std::mt19937_64 rng(sc.seed * 0x9E3779B97F4A7C15ULL + 0x6d61706d657368ULL + static_cast<std::uint64_t>(i));
    ResolvePath(spec, sc.world.bounds_m, rng);
    total_waypoints += spec.path.points.size();
    if (total_waypoints > static_cast<std::size_t>(limits::kMaxTotalWaypoints)) {
      robots.Fail(robots.Has("list") && !robots.Has("count") ? "list" : "count",
                  "the first " + std::to_string(i + 1) + " of the run's " + std::to_string(wanted) +
                      " robots already have " + std::to_string(total_waypoints) + " path waypoints (at most " +
                      std::to_string(limits::kMaxTotalWaypoints) + " in all: fewer robots or shorter paths)");
    }
    sc.robots.push_back(std::move(spec));
  }
  return sc;
}

Scenario LoadScenario(const std::string& file, const std::vector<ConfigOverride>& overrides, int agents) {
  if (auto problem = scenario_internal::RegularFileProblem(file, limits::kMaxScenarioBytes)) {
    throw ConfigError(file + ": cannot open scenario file: " + *problem);
  }
  std::ifstream in(file);
  if (!in) throw ConfigError(file + ": cannot open scenario file: not readable");
  std::stringstream text;
  text << in.rdbuf();
  return ParseScenario(text.str(), file, overrides, agents);
}

}  // namespace mapmesh
