#include "common/config/scenario_sections.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <set>
#include <sstream>

#include "common/map/map_codec.h"
#include "common/types/scenario_limits.h"

namespace mapmesh::scenario_internal {

using limits::kMaxCoordinateM;
using limits::kMaxLengthM;

namespace {

Rect ReadRect(YamlReader& r, const std::string& key, Rect def) {
  std::vector<double> v;
  r.GetVector(key, v, 4);
  if (v.empty()) return def;
  CheckCoordinates(r, key, v);
  Rect rect{v[0], v[1], v[2], v[3]};
  if (!(rect.xmax > rect.xmin && rect.ymax > rect.ymin)) {
    r.Fail(key, "expected [xmin, ymin, xmax, ymax] with xmax > xmin and ymax > ymin");
  }
  return rect;
}

// Reads an optional point [x, y] into out.
void ReadPoint(YamlReader& r, const std::string& key, Eigen::Vector2d& out) {
  std::vector<double> v;
  r.GetVector(key, v, 2);
  if (v.empty()) return;
  CheckCoordinates(r, key, v);
  out = {v[0], v[1]};
}

// Reads a list of at most max_points points [x, y].
std::vector<Eigen::Vector2d> ReadPoints(YamlReader& r, const std::string& key, int max_points) {
  std::vector<Eigen::Vector2d> pts;
  const YAML::Node n = r.Raw(key);
  if (!n || n.IsNull()) return pts;
  if (!n.IsSequence()) r.Fail(key, "expected a list of [x, y] points");
  if (n.size() > static_cast<std::size_t>(max_points)) {
    r.Fail(key, "at most " + std::to_string(max_points) + " points (got " + std::to_string(n.size()) + ")");
  }
  for (std::size_t i = 0; i < n.size(); ++i) {
    const YAML::Node& p = n[i];
    const std::string path = r.KeyPath(key) + "[" + std::to_string(i) + "]";
    if (!p.IsSequence() || p.size() != 2) r.FailAt(p, path, "expected a point [x, y]");
    Eigen::Vector2d v;
    try {
      v = {p[0].as<double>(), p[1].as<double>()};
    } catch (const YAML::Exception&) {
      r.FailAt(p, path, "expected a point [x, y] of numbers");
    }
    if (!v.allFinite()) r.FailAt(p, path, "values must be finite");
    if (v.cwiseAbs().maxCoeff() > kMaxCoordinateM) {
      r.FailAt(p, path, "coordinates must be within +-" + FormatNumber(kMaxCoordinateM) + " m");
    }
    pts.push_back(v);
  }
  return pts;
}

// Reads a list of at most kMaxRadioWalls walls [x1, y1, x2, y2], each with two distinct ends.
std::vector<RadioWall> ReadWalls(YamlReader& r, const std::string& key) {
  std::vector<RadioWall> walls;
  const YAML::Node n = r.Raw(key);
  if (!n || n.IsNull()) return walls;
  if (!n.IsSequence()) r.Fail(key, "expected a list of walls [x1, y1, x2, y2]");
  if (n.size() > static_cast<std::size_t>(limits::kMaxRadioWalls)) {
    r.Fail(key, "at most " + std::to_string(limits::kMaxRadioWalls) + " walls (got " + std::to_string(n.size()) + ")");
  }
  for (std::size_t i = 0; i < n.size(); ++i) {
    const YAML::Node& w = n[i];
    const std::string path = r.KeyPath(key) + "[" + std::to_string(i) + "]";
    std::vector<double> v;
    if (w.IsSequence() && w.size() == 4) {
      try {
        for (const YAML::Node& x : w) v.push_back(x.as<double>());
      } catch (const YAML::Exception&) {
        v.clear();
      }
    }
    if (v.size() != 4) r.FailAt(w, path, "expected a wall [x1, y1, x2, y2] of numbers");
    for (double x : v) {
      if (!std::isfinite(x) || std::abs(x) > kMaxCoordinateM) {
        r.FailAt(w, path, "coordinates must be finite and within +-" + FormatNumber(kMaxCoordinateM) + " m");
      }
    }
    if (v[0] == v[2] && v[1] == v[3]) r.FailAt(w, path, "a wall's two ends must differ");
    walls.push_back({{v[0], v[1]}, {v[2], v[3]}});
  }
  return walls;
}

// Reads "x,y" rows; blank lines, '#' comments and a non-numeric header row are skipped. The
// file must be a regular, readable file of at most kMaxCsvBytes holding 1 to kMaxLandmarks rows.
std::vector<Eigen::Vector2d> ReadLandmarkCsv(YamlReader& r, const std::string& key, const std::string& path) {
  if (auto problem = RegularFileProblem(path, limits::kMaxCsvBytes)) {
    r.Fail(key, "cannot open landmarks file '" + path + "': " + *problem);
  }
  std::ifstream in(path);
  if (!in) r.Fail(key, "cannot open landmarks file '" + path + "': not readable");
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
    const std::string where = path + ":" + std::to_string(lineno) + ": ";
    if (!(s >> x >> y)) {
      if (lineno == 1) continue;  // header row
      r.Fail(key, where + "expected 'x,y'");
    }
    if (!(std::abs(x) <= kMaxCoordinateM && std::abs(y) <= kMaxCoordinateM)) {
      r.Fail(key, where + "coordinates must be within +-" + FormatNumber(kMaxCoordinateM) + " m");
    }
    if (pts.size() == static_cast<std::size_t>(limits::kMaxLandmarks)) {
      r.Fail(key, where + "more than " + std::to_string(limits::kMaxLandmarks) + " landmarks");
    }
    pts.emplace_back(x, y);
  }
  if (in.bad()) r.Fail(key, "cannot read landmarks file '" + path + "'");
  if (pts.empty()) r.Fail(key, "landmarks file '" + path + "' holds no landmarks");
  return pts;
}

Rect BoundingBox(const std::vector<Eigen::Vector2d>& pts, double margin) {
  if (pts.empty()) return {0, 0, 50, 50};
  Rect r{std::numeric_limits<double>::max(), std::numeric_limits<double>::max(), std::numeric_limits<double>::lowest(),
         std::numeric_limits<double>::lowest()};
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
  g.GetChoice("type", gen.type, kLandmarkLayouts);
  g.GetInRange("count", gen.count, 0, limits::kMaxLandmarks);
  g.GetInRange("min_spacing_m", gen.min_spacing_m, 0.0, kMaxLengthM);
  double area = 0.0;
  if (gen.type == LandmarkLayout::kDisc) {
    ReadPoint(g, "center_m", gen.center_m);
    g.GetPositiveUpTo("radius_m", gen.radius_m, kMaxLengthM);
    area = std::numbers::pi * gen.radius_m * gen.radius_m;
  } else {
    gen.area_m = ReadRect(g, "area_m", gen.area_m);
    area = gen.area_m.Width() * gen.area_m.Height();
  }
  if (gen.type == LandmarkLayout::kPark) {
    g.GetInRange("paths", gen.paths, 1, limits::kMaxParkPaths);
    g.GetInRange("path_width_m", gen.path_width_m, 0.0, kMaxLengthM);
    g.GetInRange("scatter_fraction", gen.scatter_fraction, 0.0, 1.0);
  }
  // Random sequential placement jams near 0.69 points per d^2; stay well below it so the
  // generator always finishes.
  const double max_count = 0.5 * area / (gen.min_spacing_m * gen.min_spacing_m);
  if (gen.min_spacing_m > 0 && gen.count > max_count) {
    g.Fail("count", "cannot place " + std::to_string(gen.count) + " landmarks at min_spacing_m in " +
                        (gen.type == LandmarkLayout::kDisc ? "the disc" : "area_m") + " (at most " +
                        std::to_string(static_cast<int>(max_count)) + ")");
  }
  g.Finish();
  return gen;
}

}  // namespace

void CheckCoordinates(YamlReader& r, const std::string& key, const std::vector<double>& values) {
  for (double v : values) {
    if (!(std::abs(v) <= kMaxCoordinateM)) {
      r.Fail(key, "coordinates must be within +-" + FormatNumber(kMaxCoordinateM) + " m (got " + FormatNumber(v) + ")");
    }
  }
}

std::optional<std::string> RegularFileProblem(const std::string& path, std::size_t max_bytes) {
  std::error_code ec;
  const auto status = std::filesystem::status(path, ec);
  if (ec || !std::filesystem::exists(status)) return "no such file";
  if (std::filesystem::is_directory(status)) return "it is a directory";
  if (!std::filesystem::is_regular_file(status)) return "not a regular file";
  const auto size = std::filesystem::file_size(path, ec);
  if (ec) return "cannot read its size";
  if (size > max_bytes) {
    return "larger than " + std::to_string(max_bytes >> 20) + " MiB (" + std::to_string(size) + " bytes)";
  }
  return std::nullopt;
}

WorldOptions ReadWorld(YamlReader w, const std::string& scenario_dir, bool dataset) {
  WorldOptions o;
  w.GetInRange("control_period_s", o.control_period_s, limits::kMinControlPeriodS, limits::kMaxControlPeriodS);

  YamlReader lm = w.Child("landmarks");
  const int sources = int(lm.Has("list")) + int(lm.Has("csv")) + int(lm.Has("generator"));
  if (dataset && sources > 0) {
    w.Fail("landmarks", "a dataset scenario takes its landmarks from the dataset");
  }
  if (!dataset && sources != 1) {
    w.Fail("landmarks", "give exactly one of landmarks.list, landmarks.csv, landmarks.generator");
  }
  if (lm.Has("list")) {
    o.landmarks = ReadPoints(lm, "list", limits::kMaxLandmarks);
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
  if (o.generator && o.generator->type == LandmarkLayout::kDisc) {
    const auto& g = *o.generator;
    o.bounds_m = {g.center_m.x() - g.radius_m, g.center_m.y() - g.radius_m, g.center_m.x() + g.radius_m,
                  g.center_m.y() + g.radius_m};
  } else {
    o.bounds_m = o.generator ? o.generator->area_m : BoundingBox(o.landmarks, 1.0);
  }
  o.bounds_m = ReadRect(w, "bounds_m", o.bounds_m);
  w.Finish();
  return o;
}

SourceOptions ReadSource(YamlReader r) {
  SourceOptions o;
  r.GetChoice("type", o.type, kSourceTypes);
  if (o.type == SourceType::kSimulation) {
    r.Finish();
    return o;
  }
  o.dataset = o.type == SourceType::kMrclam ? "mrclam/MRCLAM_Dataset7" : "victoria_park";
  r.Get("dataset", o.dataset);
  if (o.type == SourceType::kMrclam) {
    r.ForEach("robots", 5, [&](const YAML::Node& n, const std::string& path) {
      int id = 0;
      try {
        id = n.as<int>();
      } catch (const YAML::Exception&) {
        r.FailAt(n, path, "expected a robot number 1-5");
      }
      if (id < 1 || id > 5) r.FailAt(n, path, "MRCLAM has robots 1-5");
      if (std::find(o.robots.begin(), o.robots.end(), static_cast<RobotId>(id)) != o.robots.end()) {
        r.FailAt(n, path, "robot " + std::to_string(id) + " is listed twice");
      }
      o.robots.push_back(static_cast<RobotId>(id));
    });
    if (o.robots.empty()) o.robots = {1, 2, 3, 4, 5};
    r.GetInRange("odometry_delay_s", o.odometry_delay_s, 0.0, limits::kMaxOdometryDelayS);
  } else {
    r.GetInRange("virtual_robots", o.virtual_robots, 1, limits::kMaxRobots);
    r.GetInRange("overlap_s", o.overlap_s, 0.0, limits::kMaxDurationS);
  }
  r.Finish();
  return o;
}

void ReadMotion(YamlReader m, MotionOptions& o) {
  m.GetChoice("model", o.model, kMotionModels);
  {
    YamlReader a = m.Child("ackermann");
    a.GetPositiveUpTo("wheelbase_m", o.ackermann.wheelbase_m, limits::kMaxVehicleM);
    a.GetInRange("encoder_offset_m", o.ackermann.encoder_offset_m, 0.0, limits::kMaxVehicleM);
    a.GetInRange("laser_a_m", o.ackermann.laser_a_m, -limits::kMaxVehicleM, limits::kMaxVehicleM);
    a.GetInRange("laser_b_m", o.ackermann.laser_b_m, -limits::kMaxVehicleM, limits::kMaxVehicleM);
    a.Finish();
  }
  m.GetChoice("steering", o.steering, kSteerings);
  m.GetInRange("speed_mps", o.speed_mps, 0.0, limits::kMaxSpeedMps);
  m.GetPositiveUpTo("max_turn_rate_dps", o.max_turn_rate_dps, limits::kMaxTurnRateDps);
  m.GetInRange("sigma_v_mps", o.sigma_v_mps, 0.0, limits::kMaxSigmaVMps);
  m.GetInRange("sigma_w_radps", o.sigma_w_radps, 0.0, limits::kMaxSigmaWRadps);
  m.GetInRange("sigma_steering_rad", o.sigma_steering_rad, 0.0, limits::kMaxSigmaSteeringRad);
  m.GetPositiveUpTo("waypoint_radius_m", o.waypoint_radius_m, kMaxLengthM);
  m.GetInRange("odometry_every_steps", o.odometry_every_steps, 1, limits::kMaxScanEverySteps);
  m.Finish();
}

void ReadSensor(YamlReader s, SensorOptions& o) {
  s.GetInRange("max_range_m", o.max_range_m, 0.0, kMaxLengthM);
  s.GetPositiveUpTo("fov_deg", o.fov_deg, 360.0);
  s.GetInRange("sigma_range_m", o.sigma_range_m, 0.0, limits::kMaxSigmaRangeM);
  s.GetInRange("sigma_bearing_deg", o.sigma_bearing_deg, 0.0, limits::kMaxSigmaBearingDeg);
  s.GetInRange("scan_every_steps", o.scan_every_steps, 1, limits::kMaxScanEverySteps);
  s.Get("scan_at_start", o.scan_at_start);
  s.Get("sees_robots", o.sees_robots);
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

void ReadPath(YamlReader p, PathOptions& o, const Rect& world_bounds) {
  const PathType before = o.type;
  p.GetChoice("type", o.type, kPathTypes);
  // Which keys each type takes besides type and loop.
  const std::map<PathType, std::set<std::string>> keys = {
      {PathType::kWaypoints, {"points"}},
      {PathType::kRandom, {"count", "area_m"}},
      {PathType::kCircle, {"count", "center_m", "radius_m", "start_angle_deg", "clockwise"}},
      {PathType::kLawnmower, {"area_m", "spacing_m"}},
      {PathType::kPark, {"index"}}};
  for (const char* k :
       {"points", "count", "area_m", "center_m", "radius_m", "start_angle_deg", "clockwise", "spacing_m", "index"}) {
    if (p.Has(k) && !keys.at(o.type).count(k)) {
      p.Fail(k, "not used by path type " + std::string(NameOf(kPathTypes, o.type)));
    }
  }
  if (o.type == PathType::kCircle && before != PathType::kCircle && !p.Has("count")) o.count = 36;
  if (o.type == PathType::kWaypoints) {
    o.points = ReadPoints(p, "points", limits::kMaxWaypoints);
    if (o.points.empty()) p.Fail("points", "type waypoints needs at least one point");
  }
  p.GetInRange("count", o.count, 1, limits::kMaxWaypoints);
  if (p.Has("area_m")) o.area_m = ReadRect(p, "area_m", Rect{});
  ReadPoint(p, "center_m", o.center_m);
  p.GetPositiveUpTo("radius_m", o.radius_m, kMaxLengthM);
  p.GetInRange("start_angle_deg", o.start_angle_deg, -limits::kMaxAngleDeg, limits::kMaxAngleDeg);
  p.Get("clockwise", o.clockwise);
  p.GetPositiveUpTo("spacing_m", o.spacing_m, kMaxLengthM);
  p.GetInRange("index", o.index, 0, limits::kMaxRobots - 1);
  p.Get("loop", o.loop);
  if (o.type == PathType::kLawnmower) {
    // LawnmowerWaypoints: two waypoints per lane, lanes spacing_m apart across the area.
    const double lanes = std::floor(o.area_m.value_or(world_bounds).Height() / o.spacing_m) + 1.0;
    if (2.0 * lanes > limits::kMaxWaypoints) {
      p.Fail(p.Has("spacing_m") || !p.Has("area_m") ? "spacing_m" : "area_m",
             "a lawnmower with lanes spacing_m apart over its area has " + FormatNumber(2.0 * lanes) +
                 " waypoints (at most " + std::to_string(limits::kMaxWaypoints) + ")");
    }
  }
  p.Finish();
}

RadioOptions ReadRadio(YamlReader r) {
  RadioOptions o;
  r.GetChoice("model", o.model, kRadioModels);
  r.GetInRange("range_m", o.range_m, 0.0, kMaxLengthM);
  const bool log_distance = o.model == RadioModelKind::kLogDistance;
  for (const char* key :
       {"path_loss_exponent", "shadowing_sigma_db", "shadowing_period_s", "packet_error_width_db", "wall_loss_db"}) {
    if (!log_distance && r.Has(key)) r.Fail(key, "only with radio.model: log_distance");
  }
  r.GetPositiveUpTo("path_loss_exponent", o.path_loss_exponent, limits::kMaxPathLossExponent);
  r.GetInRange("shadowing_sigma_db", o.shadowing_sigma_db, 0.0, limits::kMaxDecibels);
  r.GetInRange("shadowing_period_s", o.shadowing_period_s, limits::kMinPeriodS, limits::kMaxPeriodS);
  r.GetInRange("packet_error_width_db", o.packet_error_width_db, 0.0, limits::kMaxDecibels);
  r.GetInRange("wall_loss_db", o.wall_loss_db, 0.0, limits::kMaxDecibels);
  o.walls = ReadWalls(r, "walls");
  r.GetInRange("loss_probability", o.loss_probability, 0.0, 1.0);
  r.GetInRange("bandwidth_bytes_per_s", o.bandwidth_bytes_per_s, 0.0, limits::kMaxBandwidthBytesPerS);
  r.GetInRange("latency_s", o.latency_s, 0.0, limits::kMaxLatencyS);
  r.GetInRange("latency_jitter_s", o.latency_jitter_s, 0.0, limits::kMaxLatencyS);
  r.GetInRange("links_period_s", o.links_period_s, limits::kMinPeriodS, limits::kMaxPeriodS);
  r.Finish();
  return o;
}

AgentOptions ReadAgent(YamlReader a) {
  AgentOptions o;
  o.Read(a);
  a.Finish();
  return o;
}

FeederOptions ReadFeeder(YamlReader f) {
  FeederOptions o;
  f.GetChoice("pace", o.pace, kPaces);
  f.GetInRange("realtime_factor", o.realtime_factor, limits::kMinRealtimeFactor, limits::kMaxRealtimeFactor);
  f.GetInRange("lockstep_window_s", o.lockstep_window_s, limits::kMinLockstepWindowS, limits::kMaxLockstepWindowS);
  f.GetPositiveUpTo("startup_timeout_s", o.startup_timeout_s, limits::kMaxStartupTimeoutS);
  f.GetInRange("truth_period_s", o.truth_period_s, limits::kMinPeriodS, limits::kMaxPeriodS);
  f.Get("keep_streams", o.keep_streams);
  f.Finish();
  return o;
}

FaultOptions ReadFaults(YamlReader f, double duration_s) {
  FaultOptions o;
  using Kind = FaultEvent::Kind;
  for (const auto& [key, kind] :
       {std::pair{"kill", Kind::kKill}, {"restart", Kind::kRestart}, {"pause", Kind::kPause}}) {
    f.ForEach(key, limits::kMaxFaults, [&, kind = kind](const YAML::Node& node, const std::string& path) {
      YamlReader e = f.Element(node, path);  // a mapping such as {id: 3, t: 20}
      FaultEvent ev;
      ev.kind = kind;
      int id = 0;
      e.Get("id", id);
      e.Get("t", ev.t);
      for (const char* required : {"id", "t"}) {
        if (!e.Has(required)) e.FailAt(node, path + "." + required, "missing required key");
      }
      e.CheckRange("id", id, 1, limits::kMaxRobotId);
      ev.id = static_cast<RobotId>(id);
      if (duration_s > 0.0) {
        e.CheckRange("t", ev.t, 0.0, duration_s);
      } else {
        e.CheckRange("t", ev.t, 0.0, limits::kMaxDurationS);
      }
      if (kind == Kind::kPause) {
        e.Get("seconds", ev.seconds);
        if (!e.Has("seconds")) e.FailAt(node, path + ".seconds", "missing required key");
        e.CheckPositiveUpTo("seconds", ev.seconds, limits::kMaxPauseS);
      }
      e.Finish();
      o.events.push_back(ev);
    });
  }
  YamlReader inject = f.Child("inject");
  inject.Get("cases", o.inject);
  inject.GetInRange("period_s", o.inject_period_s, limits::kMinPeriodS, limits::kMaxPeriodS);
  inject.Finish();
  f.Finish();
  return o;
}

}  // namespace mapmesh::scenario_internal
