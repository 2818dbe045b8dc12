#include "sim_feeder/mrclam.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <map>

#include "common/geometry/pose_track.h"
#include "sim_feeder/dataset_table.h"

namespace mapmesh {
namespace {

constexpr int kFirstLandmarkSubject = 6;
constexpr int kLastLandmarkSubject = 20;
constexpr double kTruthPeriodS = 0.1;

std::string RobotFile(const std::string& dir, RobotId id, const char* what) {
  return dir + "/Robot" + std::to_string(id) + "_" + what + ".dat";
}

// The ground truth (rows t, x, y, theta) at time t.
std::optional<Pose2> InterpolatePose(const std::vector<TableRow>& gt, double t) {
  return PoseAlong(
      gt, t, [](const TableRow& r) { return r.v[0]; },
      [](const TableRow& r) {
        return Pose2{r.v[1], r.v[2], r.v[3]};
      });
}

}  // namespace

ReplayData LoadMrclam(const std::string& dir, const Scenario& scenario) {
  if (!std::filesystem::is_directory(dir)) {
    throw DatasetError(dir +
                       ": MRCLAM dataset directory not found (set MAPMESH_DATASETS, or mapmesh-feeder --datasets)");
  }
  ReplayData data;
  std::map<int, int> subject_of_barcode;
  for (const TableRow& r : ReadTable(dir + "/Barcodes.dat", 2)) {
    subject_of_barcode[static_cast<int>(r.v[1])] = static_cast<int>(r.v[0]);
  }
  data.landmarks.assign(kLastLandmarkSubject - kFirstLandmarkSubject + 1,
                        Eigen::Vector2d::Constant(std::numeric_limits<double>::quiet_NaN()));
  for (const TableRow& r : ReadTable(dir + "/Landmark_Groundtruth.dat", 5)) {
    const int subject = static_cast<int>(r.v[0]);
    if (subject < kFirstLandmarkSubject || subject > kLastLandmarkSubject) {
      throw DatasetError(dir + "/Landmark_Groundtruth.dat:" + std::to_string(r.line) + ": subject " +
                         std::to_string(subject) + " is not a landmark (6-20)");
    }
    data.landmarks[subject - kFirstLandmarkSubject] = {r.v[1], r.v[2]};
  }
  data.seen.assign(data.landmarks.size(), false);

  struct Raw {
    RobotId id;
    std::vector<TableRow> odom, meas, gt;
  };
  std::vector<Raw> raw;
  double t0 = std::numeric_limits<double>::infinity();
  for (const RobotSpec& spec : scenario.robots) {
    Raw r{spec.id,
          ReadTable(RobotFile(dir, spec.id, "Odometry"), 3),
          ReadTable(RobotFile(dir, spec.id, "Measurement"), 4),
          {}};
    const std::string gt_file = RobotFile(dir, spec.id, "Groundtruth");
    if (std::filesystem::exists(gt_file)) r.gt = ReadTable(gt_file, 4);
    if (r.odom.empty()) throw DatasetError(RobotFile(dir, spec.id, "Odometry") + ": no odometry rows");
    t0 = std::min(t0, r.odom.front().v[0] + scenario.source.odometry_delay_s);
    if (!r.meas.empty()) t0 = std::min(t0, r.meas.front().v[0]);
    raw.push_back(std::move(r));
  }
  data.headings_known = true;

  for (Raw& r : raw) {
    const RobotSpec& spec = *scenario.FindRobot(r.id);
    RobotStreams s;
    s.id = r.id;
    ReplayCounts counts;
    counts.id = r.id;
    counts.odom_rows = static_cast<int>(r.odom.size());
    counts.measurement_rows = static_cast<int>(r.meas.size());

    // Scans: rows with the same time, in file order.
    for (const TableRow& m : r.meas) {
      const auto it = subject_of_barcode.find(static_cast<int>(m.v[1]));
      if (it == subject_of_barcode.end()) {
        ++counts.measurement_unknown;
        continue;
      }
      const int subject = it->second;
      Observation o;
      o.range = m.v[2];
      o.bearing = m.v[3];
      if (subject >= kFirstLandmarkSubject) {
        o.kind = ObservationKind::kLandmark;
        o.signature = spec.sensor.signatures ? subject - kFirstLandmarkSubject : -1;
        data.seen[subject - kFirstLandmarkSubject] = true;
      } else {
        if (subject == static_cast<int>(r.id)) {
          ++counts.measurement_unknown;  // a robot cannot see itself
          continue;
        }
        o.kind = ObservationKind::kRobot;
        o.signature = subject;
        ++counts.robot_sightings;
      }
      const double t = m.v[0] - t0;
      if (s.scans.empty() || s.scans.back().stamp != t) {
        s.scans.push_back({r.id, static_cast<std::uint32_t>(s.scans.size()), t, {}});
      }
      s.scans.back().obs.push_back(o);
    }

    // Odometry: row i holds from its time (plus the command delay) to the next row's.
    std::vector<TableRow> rows;
    for (TableRow o : r.odom) {
      o.v[0] += scenario.source.odometry_delay_s;
      if (!rows.empty() && o.v[0] <= rows.back().v[0]) {
        ++counts.odom_duplicate_rows;
        continue;
      }
      rows.push_back(o);
    }
    const double first_row_t = rows.front().v[0] - t0;
    if (!s.scans.empty() && s.scans.front().stamp <= first_row_t) {
      // A measurement at or before the first command: a still interval covers it.
      const double begin = s.scans.front().stamp - 0.01;
      s.odom.push_back({r.id, 0, first_row_t, first_row_t - begin, 0.0, 0.0, 0.0, 0, false});
    }
    double last_t = rows.back().v[0] - t0;
    if (!s.scans.empty()) last_t = std::max(last_t, s.scans.back().stamp);
    for (std::size_t i = 0; i < rows.size(); ++i) {
      const double t = rows[i].v[0] - t0;
      const double end = i + 1 < rows.size() ? rows[i + 1].v[0] - t0 : std::max(last_t, t) + 0.02;
      s.odom.push_back({r.id, static_cast<std::uint32_t>(s.odom.size()), end, end - t, rows[i].v[1], rows[i].v[2], 0.0,
                        0, false});
    }
    CountScansPerInterval(s);

    if (!r.gt.empty()) {
      const double origin_t = s.odom.front().stamp - s.odom.front().dt + t0;
      s.start = InterpolatePose(r.gt, origin_t);
      double next = -std::numeric_limits<double>::infinity();
      for (const TableRow& g : r.gt) {
        const double t = g.v[0] - t0;
        if (t < 0 || t < next) continue;
        s.truth.push_back({r.id, t, g.v[1], g.v[2], g.v[3]});
        next = t + kTruthPeriodS;
      }
    }
    data.duration_s = std::max(data.duration_s, s.odom.back().stamp);
    data.robots.push_back(std::move(s));
    data.counts.push_back(counts);
  }
  return data;
}

}  // namespace mapmesh
