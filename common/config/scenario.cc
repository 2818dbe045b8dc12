#include "common/config/scenario.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <set>
#include <sstream>

#include "common/config/yaml_reader.h"

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

WorldOptions ReadWorld(YamlReader w, const std::string& scenario_dir) {
  WorldOptions o;
  w.GetPositive("control_period_s", o.control_period_s);

  YamlReader lm = w.Child("landmarks");
  const int sources = int(lm.Has("list")) + int(lm.Has("csv")) + int(lm.Has("generator"));
  if (sources != 1) {
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
  } else {
    YamlReader g = lm.Child("generator");
    LandmarkGeneratorOptions gen;
    g.GetChoice("type", gen.type, {"uniform"});
    g.GetNonNegative("count", gen.count);
    gen.area_m = ReadRect(g, "area_m", gen.area_m);
    g.GetNonNegative("min_spacing_m", gen.min_spacing_m);
    // Random sequential placement jams near 0.69 points per d^2; stay well below it so the
    // generator always finishes.
    const double max_count =
        0.5 * gen.area_m.Width() * gen.area_m.Height() / (gen.min_spacing_m * gen.min_spacing_m);
    if (gen.min_spacing_m > 0 && gen.count > max_count) {
      g.Fail("count", "cannot place " + std::to_string(gen.count) +
                          " landmarks at min_spacing_m in area_m (at most " +
                          std::to_string(static_cast<int>(max_count)) + ")");
    }
    g.Finish();
    o.generator = gen;
  }
  lm.Finish();
  o.bounds_m = o.generator ? o.generator->area_m : BoundingBox(o.landmarks, 1.0);
  o.bounds_m = ReadRect(w, "bounds_m", o.bounds_m);
  w.Finish();
  return o;
}

void ReadMotion(YamlReader m, MotionOptions& o) {
  m.GetNonNegative("speed_mps", o.speed_mps);
  m.GetPositive("max_turn_rate_dps", o.max_turn_rate_dps);
  m.GetNonNegative("sigma_v_mps", o.sigma_v_mps);
  m.GetNonNegative("sigma_w_radps", o.sigma_w_radps);
  m.GetPositive("waypoint_radius_m", o.waypoint_radius_m);
  m.Finish();
}

void ReadSensor(YamlReader s, SensorOptions& o) {
  s.GetNonNegative("max_range_m", o.max_range_m);
  s.GetInRange("fov_deg", o.fov_deg, 1e-9, 360.0);
  s.GetNonNegative("sigma_range_m", o.sigma_range_m);
  s.GetNonNegative("sigma_bearing_deg", o.sigma_bearing_deg);
  s.GetPositive("scan_every_steps", o.scan_every_steps);
  s.Get("signatures", o.signatures);
  s.Finish();
}

void ReadPath(YamlReader p, PathOptions& o) {
  p.GetChoice("type", o.type, {"waypoints", "random"});
  if (o.type == "waypoints") {
    o.points = ReadPoints(p, "points");
    if (o.points.empty()) p.Fail("points", "type waypoints needs at least one point");
  } else if (p.Has("points")) {
    p.Fail("points", "only used with type: waypoints");
  }
  p.GetPositive("count", o.count);
  if (p.Has("area_m")) o.area_m = ReadRect(p, "area_m", Rect{});
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
  a.GetChoice("slam", o.slam, {"dead_reckoning"});
  a.GetPositive("map_publish_period_s", o.map_publish_period_s);
  a.GetPositive("status_period_s", o.status_period_s);
  a.GetPositive("association_gate_m", o.association_gate_m);
  a.Finish();
  return o;
}

FeederOptions ReadFeeder(YamlReader f) {
  FeederOptions o;
  f.GetChoice("pace", o.pace, {"lockstep", "realtime"});
  f.GetPositive("realtime_factor", o.realtime_factor);
  f.GetPositive("lockstep_window_s", o.lockstep_window_s);
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

void GenerateRandomPath(PathOptions& path, const Rect& area, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> ux(area.xmin, area.xmax), uy(area.ymin, area.ymax);
  path.points.clear();
  for (int i = 0; i < path.count; ++i) path.points.emplace_back(ux(rng), uy(rng));
}

}  // namespace

const RobotSpec* Scenario::FindRobot(RobotId id) const {
  for (const auto& r : robots) {
    if (r.id == id) return &r;
  }
  return nullptr;
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
  top.GetPositive("duration_s", sc.duration_s);

  const std::string dir = std::filesystem::path(file).parent_path().string();
  sc.world = ReadWorld(top.Child("world"), dir.empty() ? "." : dir);
  sc.radio = ReadRadio(top.Child("radio"));
  sc.agent = ReadAgent(top.Child("agent"));
  sc.feeder = ReadFeeder(top.Child("feeder"));

  // Robots: defaults, then the listed ones (each overriding defaults key by key).
  YamlReader robots = top.Child("robots");
  RobotSpec defaults;
  int count = -1;
  robots.Get("count", count);
  if (robots.Has("count")) robots.CheckNonNegative("count", count);
  {
    YamlReader d = robots.Child("defaults");
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
      spec.start = {start[0], start[1], WrapAngle(DegToRad(start[2]))};
      spec.start_given = true;
    }
    ReadMotion(r.Child("motion"), spec.motion);
    ReadSensor(r.Child("sensor"), spec.sensor);
    ReadPath(r.Child("path"), spec.path);
    r.Finish();
    listed.push_back(spec);
  });
  robots.Finish();
  top.Finish();

  int wanted = agents > 0 ? agents : (count >= 0 ? count : static_cast<int>(listed.size()));
  if (wanted == 0 && agents <= 0) {
    throw ConfigError(file + ":1: robots: the scenario has no robots (give robots.list or robots.count)");
  }

  // Resolve the run's robots: the first listed ones, then generated ones. Random draws are
  // made robot by robot from one seeded generator, so robot k is the same whatever N is.
  std::mt19937_64 rng(sc.seed ^ 0x6d61706d657368ULL);
  RobotId next_id = ids.empty() ? 1 : *ids.rbegin() + 1;
  const Rect& bounds = sc.world.bounds_m;
  for (int i = 0; i < wanted; ++i) {
    RobotSpec spec;
    if (i < static_cast<int>(listed.size())) {
      spec = listed[i];
    } else {
      spec = defaults;
      spec.id = next_id++;
    }
    std::uniform_real_distribution<double> ux(bounds.xmin, bounds.xmax), uy(bounds.ymin, bounds.ymax),
        uth(-std::numbers::pi, std::numbers::pi);
    const Pose2 drawn{ux(rng), uy(rng), uth(rng)};
    if (!spec.start_given) spec.start = drawn;
    PathOptions drawn_path = spec.path;
    GenerateRandomPath(drawn_path, spec.path.area_m.value_or(bounds), rng);
    if (spec.path.type == "random") spec.path = drawn_path;
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
