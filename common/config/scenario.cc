#include "common/config/scenario.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <random>
#include <set>
#include <sstream>

#include "common/config/yaml_reader.h"
#include "common/map/map_codec.h"

namespace mapmesh {
namespace {

Rect ReadRect(YamlReader& r, const std::string& key, Rect def) {
  std::vector<double> v;
  r.GetVector(key, v, 4);
  if (v.empty()) return def;
  Rect rect{v[0], v[1], v[2], v[3]};
  if (!(rect.xmax > rect.xmin && rect.ymax > rect.ymin)) {
    r.Fail(key, "expected [xmin, ymin, xmax, ymax] with xmax > xmin and ymax > ymin");
  }
  return rect;
}

std::vector<Eigen::Vector2d> ReadPoints(YamlReader& r, const std::string& key) {
  std::vector<Eigen::Vector2d> pts;
  const YAML::Node n = r.Raw(key);
  if (!n || n.IsNull()) return pts;
  if (!n.IsSequence()) r.Fail(key, "expected a list of [x, y] points");
  for (std::size_t i = 0; i < n.size(); ++i) {
    const YAML::Node& p = n[i];
    const std::string path = r.KeyPath(key) + "[" + std::to_string(i) + "]";
    if (!p.IsSequence() || p.size() != 2) r.FailAt(p, path, "expected a point [x, y]");
    try {
      const Eigen::Vector2d v(p[0].as<double>(), p[1].as<double>());
      if (!v.allFinite()) r.FailAt(p, path, "values must be finite");
      pts.push_back(v);
    } catch (const YAML::Exception&) {
      r.FailAt(p, path, "expected a point [x, y] of numbers");
    }
  }
  return pts;
}

// Reads "x,y" rows; blank lines, '#' comments and a non-numeric header row are skipped.
std::vector<Eigen::Vector2d> ReadLandmarkCsv(YamlReader& r, const std::string& key,
                                             const std::string& path) {
  std::ifstream in(path);
  if (!in) r.Fail(key, "cannot open landmarks file '" + path + "'");
  std::vector<Eigen::Vector2d> pts;
  std::string line;
  int lineno = 0;
  while (std::getline(in, line)) {
    ++lineno;
    const auto first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    std::replace(line.begin(), line.end(), ',', ' ');
    std::istringstream s(line);
    double x, y;
    if (!(s >> x >> y)) {
      if (lineno == 1) continue;  // header row
      r.Fail(key, path + ":" + std::to_string(lineno) + ": expected 'x,y'");
    }
    pts.emplace_back(x, y);
  }
  return pts;
}

Rect BoundingBox(const std::vector<Eigen::Vector2d>& pts, double margin) {
  if (pts.empty()) return {0, 0, 50, 50};
  Rect r{std::numeric_limits<double>::max(), std::numeric_limits<double>::max(),
         std::numeric_limits<double>::lowest(), std::numeric_limits<double>::lowest()};
  for (const auto& p : pts) {
    r.xmin = std::min(r.xmin, p.x());
    r.ymin = std::min(r.ymin, p.y());
    r.xmax = std::max(r.xmax, p.x());
    r.ymax = std::max(r.ymax, p.y());
  }
  r.xmin -= margin;
  r.ymin -= margin;
  r.xmax += margin;
  r.ymax += margin;
  return r;
}

LandmarkGeneratorOptions ReadGenerator(YamlReader g) {
  LandmarkGeneratorOptions gen;
  g.GetChoice("type", gen.type, {"uniform", "park", "disc"});
  g.GetNonNegative("count", gen.count);
  g.GetNonNegative("min_spacing_m", gen.min_spacing_m);
  double area = 0.0;
  if (gen.type == "disc") {
    std::vector<double> c;
    g.GetVector("center_m", c, 2);
    if (!c.empty()) gen.center_m = {c[0], c[1]};
    g.GetPositive("radius_m", gen.radius_m);
    area = std::numbers::pi * gen.radius_m * gen.radius_m;
  } else {
    gen.area_m = ReadRect(g, "area_m", gen.area_m);
    area = gen.area_m.Width() * gen.area_m.Height();
  }
  if (gen.type == "park") {
    g.GetPositive("paths", gen.paths);
    g.GetNonNegative("path_width_m", gen.path_width_m);
    g.GetInRange("scatter_fraction", gen.scatter_fraction, 0.0, 1.0);
  }
  // Random sequential placement jams near 0.69 points per d^2; stay well below it so the
  // generator always finishes.
  const double max_count = 0.5 * area / (gen.min_spacing_m * gen.min_spacing_m);
  if (gen.min_spacing_m > 0 && gen.count > max_count) {
    g.Fail("count", "cannot place " + std::to_string(gen.count) + " landmarks at min_spacing_m in " +
                        (gen.type == "disc" ? "the disc" : "area_m") + " (at most " +
                        std::to_string(static_cast<int>(max_count)) + ")");
  }
  g.Finish();
  return gen;
}

WorldOptions ReadWorld(YamlReader w, const std::string& scenario_dir, bool dataset) {
  WorldOptions o;
  w.GetPositive("control_period_s", o.control_period_s);

  YamlReader lm = w.Child("landmarks");
  const int sources = int(lm.Has("list")) + int(lm.Has("csv")) + int(lm.Has("generator"));
  if (dataset && sources > 0) {
    w.Fail("landmarks", "a dataset scenario takes its landmarks from the dataset");
  }
  if (!dataset && sources != 1) {
    w.Fail("landmarks", "give exactly one of landmarks.list, landmarks.csv, landmarks.generator");
  }
  if (lm.Has("list")) {
    o.landmarks = ReadPoints(lm, "list");
  } else if (lm.Has("csv")) {
    std::string csv;
    lm.Get("csv", csv);
    std::filesystem::path p(csv);
    if (p.is_relative()) p = std::filesystem::path(scenario_dir) / p;
    o.landmarks_csv = p.lexically_normal().string();
    o.landmarks = ReadLandmarkCsv(lm, "csv", o.landmarks_csv);
  } else if (lm.Has("generator")) {
    o.generator = ReadGenerator(lm.Child("generator"));
  }
  lm.Finish();
  if (o.generator && o.generator->type == "disc") {
    const auto& g = *o.generator;
    o.bounds_m = {g.center_m.x() - g.radius_m, g.center_m.y() - g.radius_m,
                  g.center_m.x() + g.radius_m, g.center_m.y() + g.radius_m};
  } else {
    o.bounds_m = o.generator ? o.generator->area_m : BoundingBox(o.landmarks, 1.0);
  }
  o.bounds_m = ReadRect(w, "bounds_m", o.bounds_m);
  w.Finish();
  return o;
}

SourceOptions ReadSource(YamlReader r) {
  SourceOptions o;
  r.GetChoice("type", o.type, {"simulation", "mrclam", "victoria_park"});
  if (o.type == "simulation") {
    r.Finish();
    return o;
  }
  o.dataset = o.type == "mrclam" ? "mrclam/MRCLAM_Dataset7" : "victoria_park";
  r.Get("dataset", o.dataset);
  if (o.type == "mrclam") {
    r.ForEach("robots", [&](const YAML::Node& n, const std::string& path) {
      int id = 0;
      try {
        id = n.as<int>();
      } catch (const YAML::Exception&) {
        r.FailAt(n, path, "expected a robot number 1-5");
      }
      if (id < 1 || id > 5) r.FailAt(n, path, "MRCLAM has robots 1-5");
      o.robots.push_back(static_cast<RobotId>(id));
    });
    if (o.robots.empty()) o.robots = {1, 2, 3, 4, 5};
    r.GetInRange("odometry_delay_s", o.odometry_delay_s, 0.0, 5.0);
  } else {
    r.GetPositive("virtual_robots", o.virtual_robots);
    r.GetNonNegative("overlap_s", o.overlap_s);
  }
  r.Finish();
  return o;
}

void ReadMotion(YamlReader m, MotionOptions& o) {
  m.GetChoice("model", o.model, {"unicycle", "ackermann"});
  {
    YamlReader a = m.Child("ackermann");
    a.GetPositive("wheelbase_m", o.ackermann.wheelbase_m);
    a.GetNonNegative("encoder_offset_m", o.ackermann.encoder_offset_m);
    a.Get("laser_a_m", o.ackermann.laser_a_m);
    a.Get("laser_b_m", o.ackermann.laser_b_m);
    a.Finish();
  }
  m.GetChoice("steering", o.steering, {"thesis", "smooth"});
  m.GetNonNegative("speed_mps", o.speed_mps);
  m.GetPositive("max_turn_rate_dps", o.max_turn_rate_dps);
  m.GetNonNegative("sigma_v_mps", o.sigma_v_mps);
  m.GetNonNegative("sigma_w_radps", o.sigma_w_radps);
  m.GetNonNegative("sigma_steering_rad", o.sigma_steering_rad);
  m.GetPositive("waypoint_radius_m", o.waypoint_radius_m);
  m.Finish();
}

void ReadSensor(YamlReader s, SensorOptions& o) {
  s.GetNonNegative("max_range_m", o.max_range_m);
  s.GetInRange("fov_deg", o.fov_deg, 1e-9, 360.0);
  s.GetNonNegative("sigma_range_m", o.sigma_range_m);
  s.GetNonNegative("sigma_bearing_deg", o.sigma_bearing_deg);
  s.GetPositive("scan_every_steps", o.scan_every_steps);
  s.Get("scan_at_start", o.scan_at_start);
  s.Get("signatures", o.signatures);
  s.Finish();
}

// Applies robots.defaults.preset (or a listed robot's preset) to motion and sensor.
void ReadPreset(YamlReader& r, RobotSpec& spec) {
  if (!r.Has("preset")) return;
  std::string preset;
  r.GetChoice("preset", preset, {"thesis", "downs"});
  if (preset == "thesis") {
    spec.motion = MotionOptions::ThesisDefaults();
    spec.sensor = SensorOptions::ThesisDefaults();
  } else if (preset == "downs") {
    spec.motion = MotionOptions::DownsDefaults();
    spec.sensor = SensorOptions::DownsDefaults();
  }
}

void ReadPath(YamlReader p, PathOptions& o) {
  const std::string before = o.type;
  p.GetChoice("type", o.type, {"waypoints", "random", "circle", "lawnmower", "park"});
  // Which keys each type takes besides type and loop.
  const std::map<std::string, std::set<std::string>> keys = {
      {"waypoints", {"points"}},
      {"random", {"count", "area_m"}},
      {"circle", {"count", "center_m", "radius_m", "start_angle_deg", "clockwise"}},
      {"lawnmower", {"area_m", "spacing_m"}},
      {"park", {"index"}}};
  for (const char* k : {"points", "count", "area_m", "center_m", "radius_m", "start_angle_deg",
                        "clockwise", "spacing_m", "index"}) {
    if (p.Has(k) && !keys.at(o.type).count(k)) p.Fail(k, "not used by path type " + o.type);
  }
  if (o.type == "circle" && before != "circle" && !p.Has("count")) o.count = 36;
  if (o.type == "waypoints") {
    o.points = ReadPoints(p, "points");
    if (o.points.empty()) p.Fail("points", "type waypoints needs at least one point");
  }
  p.GetPositive("count", o.count);
  if (p.Has("area_m")) o.area_m = ReadRect(p, "area_m", Rect{});
  std::vector<double> c;
  p.GetVector("center_m", c, 2);
  if (!c.empty()) o.center_m = {c[0], c[1]};
  p.GetPositive("radius_m", o.radius_m);
  p.Get("start_angle_deg", o.start_angle_deg);
  p.Get("clockwise", o.clockwise);
  p.GetPositive("spacing_m", o.spacing_m);
  p.GetNonNegative("index", o.index);
  p.Get("loop", o.loop);
  p.Finish();
}

RadioOptions ReadRadio(YamlReader r) {
  RadioOptions o;
  r.GetNonNegative("range_m", o.range_m);
  r.GetInRange("loss_probability", o.loss_probability, 0.0, 1.0);
  r.GetNonNegative("bandwidth_bytes_per_s", o.bandwidth_bytes_per_s);
  r.GetPositive("links_period_s", o.links_period_s);
  r.Finish();
  return o;
}

AgentOptions ReadAgent(YamlReader a) {
  AgentOptions o;
  a.GetChoice("slam", o.slam, {"cekf", "ekf", "dead_reckoning"});
  a.GetChoice("association", o.association, {"auto", "known", "icnn", "jcbb"});
  a.GetInRange("gate_probability", o.gate_probability, 0.5, 0.999999);
  a.GetPositive("new_landmark_chi2", o.new_landmark_chi2);
  a.Get("tentative", o.tentative);
  a.GetPositive("tentative_gate_m", o.tentative_gate_m);
  a.GetPositive("tentative_timeout_s", o.tentative_timeout_s);
  a.GetNonNegative("min_range_m", o.min_range_m);
  a.GetNonNegative("max_range_m", o.max_range_m);
  a.GetPositive("region_half_m", o.region_half_m);
  a.GetNonNegative("region_reach_m", o.region_reach_m);
  a.Get("first_estimates_jacobians", o.first_estimates_jacobians);
  a.Get("frame_at_first_landmark", o.frame_at_first_landmark);
  a.GetPositive("map_publish_period_s", o.map_publish_period_s);
  a.GetPositive("status_period_s", o.status_period_s);
  a.GetPositive("association_gate_m", o.association_gate_m);
  a.GetChoice("fusion", o.fusion, {"ml", "information", "ci", "ci_det", "ci_trace"});
  a.GetPositive("align_period_s", o.align_period_s);
  a.GetNonNegative("refine_period_s", o.refine_period_s);
  a.GetPositive("drop_after_failures", o.drop_after_failures);
  a.Get("relay_global_maps", o.relay_global_maps);
  a.GetNonNegative("checkpoint_period_s", o.checkpoint_period_s);
  a.GetNonNegative("silent_after_s", o.silent_after_s);
  a.GetPositive("max_alignments_per_update", o.max_alignments_per_update);
  a.GetPositive("max_peer_landmarks", o.max_peer_landmarks);
  if (o.max_peer_landmarks > static_cast<int>(kMapCodecMaxLandmarks)) {
    a.Fail("max_peer_landmarks", "must be at most " + std::to_string(kMapCodecMaxLandmarks) + " (what a map can carry)");
  }
  a.GetInRange("world_radius_m", o.world_radius_m, 1.0, kMapCodecMaxCoordinateM);
  a.GetPositive("max_landmark_sigma_m", o.max_landmark_sigma_m);
  a.GetPositive("max_stamp_jump_s", o.max_stamp_jump_s);
  a.Finish();
  return o;
}

FeederOptions ReadFeeder(YamlReader f) {
  FeederOptions o;
  f.GetChoice("pace", o.pace, {"lockstep", "realtime"});
  f.GetPositive("realtime_factor", o.realtime_factor);
  f.GetInRange("lockstep_window_s", o.lockstep_window_s, 0.01, 10.0);
  f.GetPositive("startup_timeout_s", o.startup_timeout_s);
  f.GetPositive("truth_period_s", o.truth_period_s);
  f.Finish();
  return o;
}

// Sets key_path (dots and [i] indices) in root to the YAML value, creating maps as needed.
void ApplyOverride(YAML::Node root, const ConfigOverride& o, const std::string& file) {
  YAML::Node value;
  try {
    value = YAML::Load(o.value);
  } catch (const YAML::Exception& e) {
    throw ConfigError(file + ": --set " + o.key_path + ": cannot parse value '" + o.value + "'");
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
        throw ConfigError(file + ": --set " + o.key_path + ": no element " +
                          std::to_string(*index) + " in '" + name + "'");
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
  if (path.type == "random") {
    path.points = random_points;
  } else if (path.type == "circle") {
    path.points = CircleWaypoints(path, &start);
  } else if (path.type == "lawnmower") {
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
  m.speed_mps = 1.0;              // Downs 4.2: up to 1 m/s
  m.max_turn_rate_dps = 90.0;
  m.steering = "smooth";          // Downs turns towards the waypoint, then drives
  m.sigma_v_mps = 0.01;
  m.sigma_w_radps = 0.01;
  return m;
}

SensorOptions SensorOptions::DownsDefaults() {
  SensorOptions s;
  s.max_range_m = 10.0;           // Downs 4.2: 10 m
  s.fov_deg = 45.0;               // pi / 4 arc
  s.sigma_range_m = 0.01;
  s.sigma_bearing_deg = 0.573;    // 0.01 rad
  s.scan_every_steps = 10;        // one observation a second at the 0.1 s step
  return s;
}

MotionModel MotionModelFor(const MotionOptions& motion) {
  MotionModel m;
  m.kind = motion.model == "ackermann" ? MotionModel::Kind::kAckermann : MotionModel::Kind::kUnicycle;
  m.ackermann = motion.ackermann;
  return m;
}

std::vector<Eigen::Vector2d> CircleWaypoints(const PathOptions& path, Pose2* start) {
  const double dir = path.clockwise ? -1.0 : 1.0;
  const double a0 = DegToRad(path.start_angle_deg);
  std::vector<Eigen::Vector2d> pts;
  for (int i = 1; i <= path.count; ++i) {
    const double a = a0 + dir * 2.0 * std::numbers::pi * i / path.count;
    pts.emplace_back(path.center_m.x() + path.radius_m * std::cos(a),
                     path.center_m.y() + path.radius_m * std::sin(a));
  }
  if (start) {
    *start = {path.center_m.x() + path.radius_m * std::cos(a0),
              path.center_m.y() + path.radius_m * std::sin(a0), WrapAngle(a0 + dir * std::numbers::pi / 2)};
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
  return {text.substr(0, eq), text.substr(eq + 1)};
}

Scenario ParseScenario(const std::string& yaml_text, const std::string& file,
                       const std::vector<ConfigOverride>& overrides, int agents) {
  auto source = std::make_shared<YamlSource>();
  source->file = file;
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

  YamlReader top(root, "", source);
  Scenario sc;
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
  if (sc.duration_given || !dataset) top.GetPositive("duration_s", sc.duration_s);

  const std::string dir = std::filesystem::path(file).parent_path().string();
  sc.world = ReadWorld(top.Child("world"), dir.empty() ? "." : dir, dataset);
  sc.radio = ReadRadio(top.Child("radio"));
  sc.agent = ReadAgent(top.Child("agent"));
  sc.feeder = ReadFeeder(top.Child("feeder"));
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
    robots.CheckNonNegative("count", count);
  }
  {
    YamlReader d = robots.Child("defaults");
    ReadPreset(d, defaults);
    ReadMotion(d.Child("motion"), defaults.motion);
    ReadSensor(d.Child("sensor"), defaults.sensor);
    ReadPath(d.Child("path"), defaults.path);
    d.Finish();
  }
  std::vector<RobotSpec> listed;
  std::set<RobotId> ids;
  robots.ForEach("list", [&](const YAML::Node& node, const std::string& path) {
    YamlReader r = robots.Element(node, path);
    RobotSpec spec = defaults;
    int id = 0;
    r.Get("id", id);
    if (!r.Has("id")) r.FailAt(node, path + ".id", "missing required key");
    if (id < 1) r.Fail("id", "must be a positive integer");
    if (!ids.insert(static_cast<RobotId>(id)).second) r.Fail("id", "duplicate robot id");
    spec.id = static_cast<RobotId>(id);
    std::vector<double> start;
    r.GetVector("start", start, 3);
    if (!start.empty()) {
      if (dataset) r.Fail("start", "a dataset robot starts where the data says");
      spec.start = {start[0], start[1], WrapAngle(DegToRad(start[2]))};
      spec.start_given = true;
    }
    ReadPreset(r, spec);
    ReadMotion(r.Child("motion"), spec.motion);
    ReadSensor(r.Child("sensor"), spec.sensor);
    ReadPath(r.Child("path"), spec.path);
    r.Finish();
    listed.push_back(spec);
  });
  robots.Finish();
  top.Finish();

  if (dataset) {
    // The dataset decides the robots; listed ones only adjust their settings.
    std::vector<RobotId> dataset_ids = sc.source.robots;
    if (sc.source.type == "victoria_park") {
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
  for (int i = 0; i < wanted; ++i) {
    RobotSpec spec;
    if (i < static_cast<int>(listed.size())) {
      spec = listed[i];
    } else {
      spec = defaults;
      spec.id = next_id++;
      spec.path.index = i;  // generated robots take the park's footpaths in turn
    }
    if (spec.motion.model != "unicycle") {
      throw ConfigError(file + ": robots: robot " + std::to_string(spec.id) +
                        ": motion.model " + spec.motion.model + " is only for dataset replays");
    }
    std::mt19937_64 rng(sc.seed * 0x9E3779B97F4A7C15ULL + 0x6d61706d657368ULL + static_cast<std::uint64_t>(i));
    ResolvePath(spec, sc.world.bounds_m, rng);
    sc.robots.push_back(spec);
  }
  return sc;
}

Scenario LoadScenario(const std::string& file, const std::vector<ConfigOverride>& overrides,
                      int agents) {
  std::ifstream in(file);
  if (!in) throw ConfigError(file + ": cannot open scenario file");
  std::stringstream text;
  text << in.rdbuf();
  return ParseScenario(text.str(), file, overrides, agents);
}

}  // namespace mapmesh
