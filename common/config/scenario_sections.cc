#include "common/config/scenario_sections.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <set>
#include <sstream>

namespace mapmesh::scenario_internal {
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

}  // namespace

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

}  // namespace mapmesh::scenario_internal
