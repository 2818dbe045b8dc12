#include "sim_feeder/play_record.h"

#include <algorithm>
#include <utility>

#include "common/types/choice.h"

namespace mapmesh {

using io::json;

PlayRecord::PlayRecord(const Scenario& sc, const FeedSource& source, std::vector<ReplayCounts> counts)
    : sc_(sc), counts_(std::move(counts)), links_(sc.radio.links_period_s) {
  truth_.scenario = sc.name;
  truth_.duration_s = sc.duration_s;
  truth_.landmarks = source.Truth().landmarks;
  truth_.headings_known = source.Truth().headings_known;
  for (const RobotSpec& r : sc.robots) {
    io::RobotTruth rt;
    rt.id = r.id;
    for (const auto& [id, start] : source.Truth().starts) {
      if (id == r.id) rt.start = start;
    }
    truth_.robots.push_back(rt);
  }
}

void PlayRecord::Add(const FeedBatch& b) {
  played_until_ = std::max(played_until_, b.stamp);
  if (b.links) links_.Add(*b.links);
  for (const GroundTruth& g : b.truth) {
    double& next = next_sample_[g.robot_id];
    if (g.stamp + 1e-9 < next) continue;
    for (auto& r : truth_.robots) {
      if (r.id == g.robot_id) r.trajectory.push_back({g.stamp, {g.x, g.y, g.theta}});
    }
    next = g.stamp + sc_.feeder.truth_period_s;
  }
}

void PlayRecord::Write(const std::string& dir, const FeedSource& source, double wall_s, bool interrupted,
                       std::uint64_t resent, std::uint64_t replayed) {
  const auto& seen = source.Truth().seen;
  truth_.seen.clear();
  for (std::size_t i = 0; i < seen.size(); ++i) {
    if (seen[i]) truth_.seen.push_back(static_cast<int>(i));
  }
  io::WriteJsonAtomic(dir + "/truth.json", io::TruthToJson(truth_));
  json robots = json::array();
  for (const RobotSpec& r : sc_.robots) {
    json e = {{"id", r.id}, {"odom_sent", odom_sent_[r.id]}, {"scans_sent", scans_sent_[r.id]}};
    for (const ReplayCounts& c : counts_) {
      if (c.id != r.id) continue;
      e["odom_rows"] = c.odom_rows;
      e["odom_duplicate_rows"] = c.odom_duplicate_rows;
      e["measurement_rows"] = c.measurement_rows;
      e["measurement_unknown_barcode"] = c.measurement_unknown;
      e["robot_sightings"] = c.robot_sightings;
    }
    robots.push_back(e);
  }
  json spans = json::array();
  for (const LinkSpans::Span& sp : links_.spans()) spans.push_back({sp.a, sp.b, sp.start, sp.end});
  const json links = {{"model", std::string(NameOf(kRadioModels, sc_.radio.model))},
                      {"period_s", sc_.radio.links_period_s},
                      {"tables", links_.tables()},
                      {"spans", spans}};
  io::WriteJsonAtomic(dir + "/feeder.json", {{"scenario", sc_.name},
                                             {"source", std::string(NameOf(kSourceTypes, sc_.source.type))},
                                             {"sim_duration_s", sc_.duration_s},
                                             {"played_until_s", played_until_},
                                             {"wall_s", wall_s},
                                             {"pace", std::string(NameOf(kPaces, sc_.feeder.pace))},
                                             {"interrupted", interrupted},
                                             {"sensor_messages_resent", resent},
                                             {"sensor_messages_replayed", replayed},
                                             {"robots", robots},
                                             {"links", links}});
}

}  // namespace mapmesh
