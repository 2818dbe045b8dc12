#include "common/io/run_files.h"

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <stdexcept>

#include "common/geometry/pose_track.h"

namespace mapmesh::io {

json TrajectoryToJson(const std::vector<PoseStamp>& poses, std::optional<double> frame_origin_stamp) {
  json out = json::array();
  for (const PoseStamp& p : poses) out.push_back({p.t, p.pose.x, p.pose.y, p.pose.theta});
  return {{"frame_origin_stamp", frame_origin_stamp ? json(*frame_origin_stamp) : json()}, {"poses", out}};
}

json MapToJson(const LandmarkMap& map) {
  json lms = json::array();
  for (const Landmark& l : map.landmarks) {
    lms.push_back({{"id", l.id},
                   {"signature", l.signature},
                   {"x", l.mean.x()},
                   {"y", l.mean.y()},
                   {"cov", {l.cov(0, 0), l.cov(0, 1), l.cov(1, 1)}}});
  }
  return {{"shape_sigma_m", map.shape_sigma_m}, {"landmarks", lms}};
}

json GlobalMapToJson(const GlobalMap& g) {
  json j = MapToJson(g.map);
  for (std::size_t i = 0; i < g.map.size() && i < g.origins.size(); ++i) {
    json o = json::array();
    for (const LandmarkOrigin& x : g.origins[i]) {
      o.push_back(x.relayed ? json{x.robot, x.incarnation, x.id, 1} : json{x.robot, x.incarnation, x.id});
    }
    j["landmarks"][i]["origins"] = o;
  }
  j["origins_mark_relays"] = true;  // files written before the mark existed lack this
  const GlobalMapStats& s = g.stats;
  j["stats"] = {{"local", s.local},
                {"sources", s.sources},
                {"rejected_sources", s.rejected_sources},
                {"associated", s.associated},
                {"appended", s.appended},
                {"rejected_landmarks", s.rejected_landmarks},
                {"ambiguous_groups", s.ambiguous_groups},
                {"greedy_groups", s.greedy_groups}};
  return j;
}

LandmarkMap MapFromJson(const json& j) {
  LandmarkMap map;
  try {
    map.shape_sigma_m = j.value("shape_sigma_m", 0.0);
    for (const auto& e : j.at("landmarks")) {
      Landmark l;
      l.id = e.at("id").get<std::uint32_t>();
      l.signature = e.value("signature", -1);
      l.mean = {e.at("x").get<double>(), e.at("y").get<double>()};
      const auto& c = e.at("cov");
      l.cov << c.at(0).get<double>(), c.at(1).get<double>(), c.at(1).get<double>(), c.at(2).get<double>();
      map.landmarks.push_back(l);
    }
  } catch (const json::exception& ex) {
    throw std::runtime_error(std::string("malformed map: ") + ex.what());
  }
  return map;
}

std::optional<Pose2> RobotTruth::PoseAt(double t) const {
  return PoseAlong(
      trajectory, t, [](const TruthSample& s) { return s.t; }, [](const TruthSample& s) { return s.pose; });
}

const RobotTruth* RunTruth::Find(RobotId id) const {
  for (const auto& r : robots) {
    if (r.id == id) return &r;
  }
  return nullptr;
}

json ResolvedToJson(const ResolvedScenario& resolved) {
  json out = json::object();
  for (const auto& [key, v] : resolved) {
    switch (v.kind) {
      case ResolvedValue::Kind::kNumber: out[key] = json::parse(v.text); break;
      case ResolvedValue::Kind::kBool: out[key] = v.text == "true"; break;
      case ResolvedValue::Kind::kString: out[key] = v.text; break;
      case ResolvedValue::Kind::kYaml: {
        json parsed = json::parse(v.text, nullptr, /*allow_exceptions=*/false);
        out[key] = parsed.is_discarded() ? json(v.text) : std::move(parsed);
        break;
      }
    }
  }
  return out;
}

json TruthToJson(const RunTruth& truth) {
  json lms = json::array();
  for (std::size_t i = 0; i < truth.landmarks.size(); ++i) {
    lms.push_back({{"id", i}, {"x", truth.landmarks[i].x()}, {"y", truth.landmarks[i].y()}});
  }
  json robots = json::array();
  for (const RobotTruth& r : truth.robots) {
    json traj = json::array();
    for (const TruthSample& s : r.trajectory) {
      traj.push_back({s.t, s.pose.x, s.pose.y, s.pose.theta});
    }
    robots.push_back({{"id", r.id},
                      {"start", r.start ? json{r.start->x, r.start->y, r.start->theta} : json()},
                      {"trajectory", traj}});
  }
  return {{"scenario", truth.scenario}, {"duration_s", truth.duration_s},         {"landmarks", lms},
          {"seen", truth.seen},         {"headings_known", truth.headings_known}, {"robots", robots}};
}

RunTruth TruthFromJson(const json& j) {
  RunTruth t;
  try {
    t.scenario = j.value("scenario", "");
    t.duration_s = j.value("duration_s", 0.0);
    for (const auto& l : j.at("landmarks")) t.landmarks.emplace_back(l.at("x"), l.at("y"));
    t.seen = j.value("seen", std::vector<int>{});
    t.headings_known = j.value("headings_known", true);
    for (const auto& r : j.at("robots")) {
      RobotTruth rt;
      rt.id = r.at("id");
      const auto& s = r.at("start");
      if (!s.is_null()) rt.start = Pose2{s.at(0), s.at(1), s.at(2)};
      for (const auto& p : r.at("trajectory")) {
        rt.trajectory.push_back({p.at(0), {p.at(1), p.at(2), p.at(3)}});
      }
      t.robots.push_back(std::move(rt));
    }
  } catch (const json::exception& ex) {
    throw std::runtime_error(std::string("malformed truth: ") + ex.what());
  }
  return t;
}

WriteError::WriteError(const std::string& path, int error)
    : std::runtime_error(path + ": " + std::strerror(error)), error_(error) {}

void WriteFileAtomic(const std::string& path, const std::string& text) {
  const std::string tmp = path + ".tmp";
  std::FILE* f = std::fopen(tmp.c_str(), "w");
  if (!f) throw WriteError(tmp, errno);
  int error = 0;
  if (std::fwrite(text.data(), 1, text.size(), f) != text.size() || std::fflush(f) != 0) error = errno ? errno : EIO;
  if (std::fclose(f) != 0 && error == 0) error = errno ? errno : EIO;
  if (error == 0 && std::rename(tmp.c_str(), path.c_str()) != 0) error = errno ? errno : EIO;
  if (error != 0) {
    std::remove(tmp.c_str());
    throw WriteError(path, error);
  }
}

void WriteJsonAtomic(const std::string& path, const json& j) { WriteFileAtomic(path, j.dump(1) + '\n'); }

void AppendLine(const std::string& path, const std::string& line) {
  std::FILE* f = std::fopen(path.c_str(), "a");
  if (!f) throw WriteError(path, errno);
  int error = 0;
  if (std::fputs((line + '\n').c_str(), f) == EOF || std::fflush(f) != 0) error = errno ? errno : EIO;
  if (std::fclose(f) != 0 && error == 0) error = errno ? errno : EIO;
  if (error != 0) throw WriteError(path, error);
}

json ReadJson(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path + ": cannot open");
  try {
    return json::parse(in);
  } catch (const json::exception& ex) {
    throw std::runtime_error(path + ": " + ex.what());
  }
}

}  // namespace mapmesh::io
