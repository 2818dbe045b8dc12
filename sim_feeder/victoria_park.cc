#include "sim_feeder/victoria_park.h"

#include <algorithm>
#include <cmath>
#include <filesystem>

#include "sim_feeder/dataset_table.h"

namespace mapmesh {

ReplayData LoadVictoriaPark(const std::string& dir, const Scenario& scenario) {
  if (!std::filesystem::is_directory(dir)) {
    throw DatasetError(
        dir + ": Victoria Park dataset directory not found (set MAPMESH_DATASETS, or mapmesh-feeder --datasets)");
  }
  const std::vector<TableRow> inputs = ReadTable(dir + "/inputs.dat", 3);
  const std::vector<TableRow> meas = ReadTable(dir + "/measurements.dat", 4);
  const std::vector<TableRow> gps = ReadTable(dir + "/gps.dat", 3);
  if (inputs.size() < 2) throw DatasetError(dir + "/inputs.dat: too few rows");

  ReplayData data;
  data.headings_known = false;
  const int k = static_cast<int>(scenario.robots.size());
  const double t_first = inputs.front().v[0], t_last = inputs.back().v[0];
  const double overlap = scenario.source.overlap_s;
  const double length = (t_last - t_first + (k - 1) * overlap) / k;
  if (length <= overlap) {
    throw DatasetError(dir + ": " + std::to_string(k) + " virtual robots with overlap_s " + std::to_string(overlap) +
                       " leave no time for each robot");
  }
  auto first_at_or_after = [](const std::vector<TableRow>& rows, double t) {
    return std::lower_bound(rows.begin(), rows.end(), t, [](const TableRow& r, double v) { return r.v[0] < v; });
  };
  for (int i = 0; i < k; ++i) {
    const RobotSpec& spec = scenario.robots[i];
    RobotStreams s;
    s.id = spec.id;
    ReplayCounts counts;
    counts.id = spec.id;
    const double seg_begin = t_first + i * (length - overlap);
    const double seg_end = i + 1 == k ? t_last : seg_begin + length;
    auto it = first_at_or_after(inputs, seg_begin);
    // The first interval starts at the previous row (or one typical step before the data).
    const double prev_t = it == inputs.begin() ? it->v[0] - 0.025 : (it - 1)->v[0];
    const double origin = prev_t;
    for (double last = prev_t; it != inputs.end() && it->v[0] <= seg_end; ++it) {
      const double t = it->v[0];
      if (t <= last) {
        ++counts.odom_duplicate_rows;
        continue;
      }
      s.odom.push_back({spec.id, static_cast<std::uint32_t>(s.odom.size()), t - origin, t - last, it->v[1], 0.0,
                        it->v[2], 0, false});
      last = t;
      ++counts.odom_rows;
    }
    const double end = s.odom.back().stamp + origin;
    for (auto m = first_at_or_after(meas, std::nextafter(origin, origin + 1)); m != meas.end() && m->v[0] <= end; ++m) {
      const double t = m->v[0] - origin;
      if (s.scans.empty() || s.scans.back().stamp != t) {
        s.scans.push_back({spec.id, static_cast<std::uint32_t>(s.scans.size()), t, {}});
      }
      s.scans.back().obs.push_back({m->v[1], WrapAngle(m->v[2] - std::numbers::pi / 2), -1,
                                    ObservationKind::kLandmark});
      ++counts.measurement_rows;
    }
    CountScansPerInterval(s);
    for (auto g = first_at_or_after(gps, origin); g != gps.end() && g->v[0] <= end; ++g) {
      s.truth.push_back({spec.id, g->v[0] - origin, g->v[1], g->v[2], 0.0});
    }
    data.duration_s = std::max(data.duration_s, s.odom.back().stamp);
    data.robots.push_back(std::move(s));
    data.counts.push_back(counts);
  }
  return data;
}

}  // namespace mapmesh
