#include "common/io/checkpoint.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <system_error>
#include <unordered_set>
#include <utility>

#include <Eigen/Eigenvalues>
#include <nlohmann/json.hpp>

#include "common/io/base64.h"
#include "common/io/run_files.h"
#include "common/map/submap_origin.h"

namespace mapmesh::io {
namespace {

constexpr std::size_t kMaxReasonChars = 240;

// A double as a reason shows it: whole numbers in full ("100000"), others in their shortest
// round-trip form ("0.1", "1e+300").
std::string Num(double v) {
  char buf[64];
  const bool whole = std::isfinite(v) && v == std::trunc(v) && std::abs(v) < 1e15;
  const auto r = whole ? std::to_chars(buf, buf + sizeof buf, v, std::chars_format::fixed, 0)
                       : std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}

// "local.landmarks[3]" + "x" -> "local.landmarks[3].x"; the top level has no prefix.
std::string Where(const std::string& path, std::string_view key) {
  return path.empty() ? std::string(key) : path + "." + std::string(key);
}

// The deepest nesting of arrays and objects in JSON text (brackets inside strings do not
// count), counted no further than limit + 1. Malformed text is left to the parser.
std::size_t NestingDepth(std::string_view text, std::size_t limit) {
  std::size_t depth = 0, deepest = 0;
  bool in_string = false;
  for (std::size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (in_string) {
      if (c == '\\') {
        ++i;
      } else if (c == '"') {
        in_string = false;
      }
    } else if (c == '"') {
      in_string = true;
    } else if (c == '[' || c == '{') {
      deepest = std::max(deepest, ++depth);
      if (deepest > limit) return deepest;
    } else if ((c == ']' || c == '}') && depth > 0) {
      --depth;
    }
  }
  return deepest;
}

// A parser's message on one printable line of bounded length, without its exception tag.
std::string OneLine(std::string_view what) {
  if (what.starts_with("[json.exception.")) {
    const std::size_t end = what.find("] ");
    if (end != std::string_view::npos) what.remove_prefix(end + 2);
  }
  std::string out;
  for (const char c : what.substr(0, kMaxReasonChars)) {
    const auto u = static_cast<unsigned char>(c);
    out += (u < 0x20 || u >= 0x7f) ? '?' : c;
  }
  if (what.size() > kMaxReasonChars) out += "...";
  return out;
}

// Validates a parsed checkpoint document into an AgentCheckpoint; the first problem found,
// in document order, becomes the reason.
class Validator {
 public:
  Validator(std::string_view name, RobotId robot, std::uint32_t incarnation, const CheckpointLimits& limits)
      : name_(name), robot_(robot), incarnation_(incarnation), limits_(limits) {}

  // The whole document; false with error() set when it is not a valid checkpoint.
  bool Checkpoint(const nlohmann::json& doc, AgentCheckpoint* out) {
    if (!Snapshot(doc, "", out)) return false;
    // Earlier entries, depth first in document order, with an explicit stack (no recursion).
    std::vector<Pending> stack;
    if (!PushEarlier(doc, "", out->earlier.size(), &stack)) return false;
    while (!stack.empty()) {
      Pending p = std::move(stack.back());
      stack.pop_back();
      IncarnationSnapshot s;
      if (!Snapshot(*p.entry, p.where, &s)) return false;
      out->earlier.push_back(std::move(s));
      if (!PushEarlier(*p.entry, p.where, out->earlier.size(), &stack)) return false;
    }
    return Submaps(doc, &out->submaps) && Peers(doc, &out->peers);
  }

  bool Fail(std::string what) {
    error_ = std::string(name_) + ": " + std::move(what);
    return false;
  }
  const std::string& error() const { return error_; }

 private:
  using json = nlohmann::json;
  // An earlier[] entry still to validate, and its path in the document.
  struct Pending {
    const json* entry;
    std::string where;
  };

  // Pushes the entry's earlier[] children so that they pop in document order; `done` entries
  // are already out. Refuses more than limits_.max_earlier in all (so the stack stays small).
  bool PushEarlier(const json& entry, const std::string& where, std::size_t done, std::vector<Pending>* stack) {
    const auto it = entry.find("earlier");
    if (it == entry.end()) return true;
    const std::string at = Where(where, "earlier");
    if (!it->is_array()) return Fail(at + " is " + TypeOf(*it) + ", expected an array");
    if (done + stack->size() + it->size() > limits_.max_earlier) {
      return Fail(at + " makes more than " + std::to_string(limits_.max_earlier) + " earlier incarnations in all");
    }
    for (std::size_t i = it->size(); i-- > 0;) {
      stack->push_back({&(*it)[i], at + "[" + std::to_string(i) + "]"});
    }
    return true;
  }

  // One incarnation's fields (not its earlier[]).
  bool Snapshot(const json& j, const std::string& where, IncarnationSnapshot* s) {
    if (!j.is_object()) {
      return Fail((where.empty() ? "the document" : where) + " is " + TypeOf(j) + ", expected an object");
    }
    std::uint64_t robot = 0, incarnation = 0;
    if (!Unsigned(j, "robot", where, &robot)) return false;
    if (robot != robot_) {
      return Fail(Where(where, "robot") + " is " + std::to_string(robot) + ", expected " + std::to_string(robot_));
    }
    if (!Unsigned(j, "incarnation", where, &incarnation)) return false;
    const std::string at = Where(where, "incarnation");
    if (incarnation > std::numeric_limits<std::uint32_t>::max()) {
      return Fail(at + " " + std::to_string(incarnation) + " is beyond 32 bits");
    }
    if (incarnation == incarnation_) {
      return Fail(at + " " + std::to_string(incarnation) + " is the resuming process's own incarnation");
    }
    const auto [seen, fresh] = incarnations_.emplace(static_cast<std::uint32_t>(incarnation), at);
    if (!fresh) return Fail(at + " " + std::to_string(incarnation) + " repeats " + seen->second);
    s->robot = static_cast<RobotId>(robot);
    s->incarnation = static_cast<std::uint32_t>(incarnation);
    if (!Stamp(j, "origin_stamp", where, &s->origin_stamp)) return false;
    if (!Stamp(j, "processed_until", where, &s->processed_until)) return false;
    return Map(j, "local", where, &s->local) && Map(j, "global", where, &s->global);
  }

  // The top level's "submaps" (optional): base64 strings, each a valid submap, or objects of
  // such a string ("submap") and its signature ("signature", base64, not empty).
  bool Submaps(const json& doc, std::vector<SubmapBlob>* out) {
    const auto it = doc.find("submaps");
    if (it == doc.end()) return true;
    if (!it->is_array()) return Fail("submaps is " + TypeOf(*it) + ", expected an array");
    if (it->size() > limits_.max_submaps) {
      return Fail("submaps holds " + std::to_string(it->size()) + " submaps, more than the limit of " +
                  std::to_string(limits_.max_submaps));
    }
    std::map<SubmapId, std::size_t> seen;
    out->reserve(it->size());
    for (std::size_t i = 0; i < it->size(); ++i) {
      const json& e = (*it)[i];
      const std::string at = "submaps[" + std::to_string(i) + "]";
      SubmapBlob blob;
      const json* text = &e;
      std::string field = at;
      if (e.is_object()) {
        if (e.size() != 2)
          return Fail(at + " has " + std::to_string(e.size()) + " keys, expected submap and signature");
        const json* sig = Member(e, "signature", at);
        if (sig == nullptr) return false;
        if (!sig->is_string()) return Fail(at + ".signature is " + TypeOf(*sig) + ", expected a base64 string");
        std::optional<std::vector<std::uint8_t>> s = Base64Decode(sig->get_ref<const std::string&>());
        if (!s) return Fail(at + ".signature is not base64 (padded, the standard alphabet, no whitespace)");
        if (s->empty() || s->size() > kMaxSubmapSignatureBytes) {
          return Fail(at + ".signature holds " + std::to_string(s->size()) + " bytes, expected 1 to " +
                      std::to_string(kMaxSubmapSignatureBytes));
        }
        blob.signature = std::move(*s);
        text = Member(e, "submap", at);
        if (text == nullptr) return false;
        field = at + ".submap";
      }
      if (!text->is_string()) return Fail(field + " is " + TypeOf(*text) + ", expected a base64 string");
      std::optional<std::vector<std::uint8_t>> bytes = Base64Decode(text->get_ref<const std::string&>());
      if (!bytes) return Fail(field + " is not base64 (padded, the standard alphabet, no whitespace)");
      const SubmapDecodeResult d = DecodeSubmap(*bytes);
      if (!d.ok()) return Fail(at + " is not a submap: " + std::string(ToString(d.error)));
      const SubmapId& id = d.submap.id;
      const std::string name = std::to_string(id.robot) + "." + std::to_string(id.incarnation) + "." +
                               std::to_string(id.index);
      if (id.robot == robot_ && id.incarnation == incarnation_) {
        return Fail(at + " (" + name + ") is of the resuming process's own incarnation");
      }
      if (const MapLimitViolation v = CheckSubmapLimits(d.submap, limits_.submap_limits);
          v != MapLimitViolation::kNone) {
        return Fail(at + " (" + name + ") is beyond the limits: " + std::string(ToString(v)));
      }
      if (d.submap.closed_s > limits_.max_stamp_s) {
        return Fail(at + " (" + name + ") closes at " + Num(d.submap.closed_s) + " s, after the end of the run (" +
                    Num(limits_.max_stamp_s) + " s)");
      }
      const auto [first, fresh] = seen.emplace(id, i);
      if (!fresh)
        return Fail(at + " repeats the identity " + name + " of submaps[" + std::to_string(first->second) + "]");
      blob.bytes = std::move(*bytes);
      out->push_back(std::move(blob));
    }
    return true;
  }

  // The top level's "peers" (optional, issue R3): the peers' frames as the agent had placed them.
  bool Peers(const json& doc, std::vector<PeerAlignment>* out) {
    const auto it = doc.find("peers");
    if (it == doc.end()) return true;
    if (!it->is_array()) return Fail("peers is " + TypeOf(*it) + ", expected an array");
    if (it->size() > limits_.max_peers) {
      return Fail("peers holds " + std::to_string(it->size()) + " alignments, more than the limit of " +
                  std::to_string(limits_.max_peers));
    }
    std::map<std::pair<std::uint64_t, std::uint64_t>, std::size_t> seen;
    out->reserve(it->size());
    for (std::size_t i = 0; i < it->size(); ++i) {
      const json& e = (*it)[i];
      const std::string at = "peers[" + std::to_string(i) + "]";
      if (!e.is_object()) return Fail(at + " is " + TypeOf(e) + ", expected an object");
      PeerAlignment a;
      std::uint64_t robot = 0, incarnation = 0;
      if (!Unsigned(e, "robot", at, &robot) || !Unsigned(e, "incarnation", at, &incarnation)) return false;
      if (robot > std::numeric_limits<RobotId>::max() || incarnation > std::numeric_limits<std::uint32_t>::max()) {
        return Fail(at + " names robot " + std::to_string(robot) + " incarnation " + std::to_string(incarnation) +
                    ", beyond 32 bits");
      }
      if (robot == robot_) return Fail(at + " is of robot " + std::to_string(robot) + ", the agent's own");
      const auto [first, fresh] = seen.emplace(std::pair{robot, incarnation}, i);
      if (!fresh) {
        return Fail(at + " repeats robot " + std::to_string(robot) + " incarnation " + std::to_string(incarnation) +
                    " of peers[" + std::to_string(first->second) + "]");
      }
      a.robot = static_cast<RobotId>(robot);
      a.incarnation = static_cast<std::uint32_t>(incarnation);
      if (!Stamp(e, "origin_stamp", at, &a.origin_stamp) || !Stamp(e, "frame_stamp", at, &a.frame_stamp)) return false;
      double pose[3];
      for (int k = 0; k < 3; ++k) {
        const char* key = k == 0 ? "x" : k == 1 ? "y" : "theta";
        const json* v = Member(e, key, at);
        if (v == nullptr || !Finite(*v, Where(at, key), &pose[k])) return false;
        const double bound = k < 2 ? limits_.max_abs_coordinate_m : 4.0;  // theta: wrapped, in [-pi, pi]
        if (std::abs(pose[k]) > bound) {
          return Fail(Where(at, key) + " is " + Num(pose[k]) +
                      (k < 2 ? " m, beyond the world bound of " + Num(bound) + " m"
                             : " rad, expected an angle wrapped to [-pi, pi]"));
        }
      }
      a.to_own = Pose2{pose[0], pose[1], pose[2]};
      const json* c = Member(e, "cov", at);
      if (c == nullptr) return false;
      if (!c->is_array() || c->size() != 9) {
        return Fail(at + ".cov is " + TypeOf(*c) + ", expected an array of 9 numbers (3 x 3, row by row)");
      }
      for (int k = 0; k < 9; ++k) {
        if (!Finite((*c)[k], at + ".cov[" + std::to_string(k) + "]", &a.cov(k / 3, k % 3))) return false;
      }
      const double scale = std::max(1.0, a.cov.cwiseAbs().maxCoeff());
      const bool symmetric = (a.cov - a.cov.transpose()).cwiseAbs().maxCoeff() <= 1e-12 * scale;
      if (!symmetric ||
          Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(a.cov).eigenvalues().minCoeff() < -1e-12 * scale) {
        return Fail(at + ".cov is not symmetric positive semi-definite");
      }
      out->push_back(a);
    }
    return true;
  }

  // The member `key` of object j, or nullptr after failing with "missing".
  const json* Member(const json& j, std::string_view key, const std::string& where) {
    const auto it = j.find(key);
    if (it == j.end()) {
      Fail(Where(where, key) + " is missing");
      return nullptr;
    }
    return &*it;
  }

  bool Unsigned(const json& j, std::string_view key, const std::string& where, std::uint64_t* out) {
    const json* v = Member(j, key, where);
    if (v == nullptr) return false;
    if (v->is_number_unsigned()) {
      *out = v->get<std::uint64_t>();
      return true;
    }
    if (v->is_number_integer()) {
      return Fail(Where(where, key) + " is " + std::to_string(v->get<std::int64_t>()) + ", expected an integer >= 0");
    }
    return Fail(Where(where, key) + " is " + TypeOf(*v) + ", expected an integer >= 0");
  }

  // A finite number; null is what a NaN or an infinity becomes when written as JSON.
  bool Finite(const json& v, const std::string& at, double* out) {
    if (!v.is_number()) {
      return Fail(at + " is " + TypeOf(v) + ", expected a finite number" +
                  (v.is_null() ? " (NaN and inf are written as null)" : ""));
    }
    *out = v.get<double>();
    if (!std::isfinite(*out)) return Fail(at + " is " + Num(*out) + ", expected a finite number");
    return true;
  }

  bool Stamp(const json& j, std::string_view key, const std::string& where, double* out) {
    const json* v = Member(j, key, where);
    if (v == nullptr || !Finite(*v, Where(where, key), out)) return false;
    if (*out < 0) return Fail(Where(where, key) + " is " + Num(*out) + ", expected >= 0");
    if (*out > limits_.max_stamp_s) {
      return Fail(Where(where, key) + " is " + Num(*out) + " s, after the end of the run (" + Num(limits_.max_stamp_s) +
                  " s)");
    }
    return true;
  }

  // {"shape_sigma_m" (optional), "landmarks": [{"id", "signature" (optional), "x", "y",
  // "cov": [xx, xy, yy]}...]}, as io::MapToJson writes it.
  bool Map(const json& j, std::string_view key, const std::string& where, LandmarkMap* map) {
    const json* m = Member(j, key, where);
    if (m == nullptr) return false;
    const std::string at = Where(where, key);
    if (!m->is_object()) return Fail(at + " is " + TypeOf(*m) + ", expected an object");
    if (const auto s = m->find("shape_sigma_m"); s != m->end()) {
      if (!Finite(*s, at + ".shape_sigma_m", &map->shape_sigma_m)) return false;
      if (map->shape_sigma_m < 0) return Fail(at + ".shape_sigma_m is " + Num(map->shape_sigma_m) + ", expected >= 0");
    }
    const json* lms = Member(*m, "landmarks", at);
    if (lms == nullptr) return false;
    if (!lms->is_array()) return Fail(at + ".landmarks is " + TypeOf(*lms) + ", expected an array");
    if (lms->size() > limits_.max_landmarks) {
      return Fail(at + ".landmarks holds " + std::to_string(lms->size()) + " landmarks, more than the limit of " +
                  std::to_string(limits_.max_landmarks));
    }
    map->landmarks.reserve(lms->size());
    std::unordered_set<std::uint32_t> ids;
    ids.reserve(lms->size());
    for (std::size_t i = 0; i < lms->size(); ++i) {
      const std::string lat = at + ".landmarks[" + std::to_string(i) + "]";
      Landmark l;
      if (!OneLandmark((*lms)[i], lat, &l)) return false;
      if (!ids.insert(l.id).second) return Fail(lat + ".id " + std::to_string(l.id) + " is a duplicate in " + at);
      map->landmarks.push_back(l);
    }
    return true;
  }

  bool OneLandmark(const json& e, const std::string& at, Landmark* l) {
    if (!e.is_object()) return Fail(at + " is " + TypeOf(e) + ", expected an object");
    std::uint64_t id = 0;
    if (!Unsigned(e, "id", at, &id)) return false;
    if (id > std::numeric_limits<std::uint32_t>::max()) {
      return Fail(at + ".id " + std::to_string(id) + " is beyond 32 bits");
    }
    l->id = static_cast<std::uint32_t>(id);
    if (const auto s = e.find("signature"); s != e.end()) {
      constexpr std::int64_t kMin = std::numeric_limits<std::int32_t>::min();
      constexpr std::uint64_t kMax = std::numeric_limits<std::int32_t>::max();
      const bool fits = s->is_number_unsigned() ? s->get<std::uint64_t>() <= kMax
                                                : s->is_number_integer() && s->get<std::int64_t>() >= kMin;
      if (!fits) return Fail(at + ".signature is " + TypeOf(*s) + ", expected a 32-bit integer");
      l->signature = static_cast<std::int32_t>(s->get<std::int64_t>());
    }
    for (int axis = 0; axis < 2; ++axis) {
      const char* name = axis == 0 ? "x" : "y";
      const json* v = Member(e, name, at);
      if (v == nullptr || !Finite(*v, Where(at, name), &l->mean[axis])) return false;
      if (std::abs(l->mean[axis]) > limits_.max_abs_coordinate_m) {
        return Fail(Where(at, name) + " is " + Num(l->mean[axis]) + " m, beyond the world bound of " +
                    Num(limits_.max_abs_coordinate_m) + " m");
      }
    }
    const json* c = Member(e, "cov", at);
    if (c == nullptr) return false;
    if (!c->is_array() || c->size() != 3) {
      return Fail(at + ".cov is " + TypeOf(*c) + ", expected an array [xx, xy, yy] of 3 numbers");
    }
    double v[3];
    for (int k = 0; k < 3; ++k) {
      if (!Finite((*c)[k], at + ".cov[" + std::to_string(k) + "]", &v[k])) return false;
    }
    l->cov << v[0], v[1], v[1], v[2];
    if (!IsValidCovariance(l->cov)) {
      return Fail(at + ".cov [" + Num(v[0]) + ", " + Num(v[1]) + ", " + Num(v[2]) + "] is not positive semi-definite");
    }
    return true;
  }

  // How a value appears in a reason: numbers as themselves, anything else by its type.
  static std::string TypeOf(const json& v) {
    if (v.is_number_unsigned()) return std::to_string(v.get<std::uint64_t>());
    if (v.is_number_integer()) return std::to_string(v.get<std::int64_t>());
    if (v.is_number()) {
      std::string n = Num(v.get<double>());
      if (n.find_first_of(".en") == std::string::npos) n += ".0";  // 3.0, not 3
      return n;
    }
    if (v.is_null()) return "null";
    if (v.is_boolean()) return v.get<bool>() ? "true" : "false";
    if (v.is_array()) return "an array of " + std::to_string(v.size());
    if (v.is_object()) return "an object";
    return std::string("a ") + v.type_name();
  }

  std::string_view name_;
  RobotId robot_;
  std::uint32_t incarnation_;
  const CheckpointLimits& limits_;
  std::map<std::uint32_t, std::string> incarnations_;  // seen so far, and where
  std::string error_;
};

CheckpointLoad Failed(std::string error) {
  CheckpointLoad r;
  r.error = std::move(error);
  return r;
}

}  // namespace

nlohmann::json CheckpointToJson(const AgentCheckpoint& c) {
  const auto snapshot = [](const IncarnationSnapshot& s) {
    return nlohmann::json{{"robot", s.robot},
                          {"incarnation", s.incarnation},
                          {"origin_stamp", s.origin_stamp},
                          {"processed_until", s.processed_until},
                          {"local", MapToJson(s.local)},
                          {"global", MapToJson(s.global)}};
  };
  nlohmann::json earlier = nlohmann::json::array();
  for (const IncarnationSnapshot& e : c.earlier) earlier.push_back(snapshot(e));
  nlohmann::json j = snapshot(c);
  j["earlier"] = std::move(earlier);
  nlohmann::json submaps = nlohmann::json::array();
  for (const SubmapBlob& b : c.submaps) {
    if (b.signature.empty()) {
      submaps.push_back(Base64Encode(b.bytes));
    } else {
      submaps.push_back({{"submap", Base64Encode(b.bytes)}, {"signature", Base64Encode(b.signature)}});
    }
  }
  j["submaps"] = std::move(submaps);
  nlohmann::json peers = nlohmann::json::array();
  for (const PeerAlignment& a : c.peers) {
    nlohmann::json cov = nlohmann::json::array();
    for (int k = 0; k < 9; ++k) cov.push_back(a.cov(k / 3, k % 3));
    peers.push_back({{"robot", a.robot},
                     {"incarnation", a.incarnation},
                     {"origin_stamp", a.origin_stamp},
                     {"frame_stamp", a.frame_stamp},
                     {"x", a.to_own.x},
                     {"y", a.to_own.y},
                     {"theta", a.to_own.theta},
                     {"cov", std::move(cov)}});
  }
  j["peers"] = std::move(peers);
  return j;
}

CheckpointLoad ParseCheckpoint(std::string_view text, std::string_view name, RobotId robot, std::uint32_t incarnation,
                               const CheckpointLimits& limits) {
  const std::string label(name);
  if (NestingDepth(text, limits.MaxJsonDepth()) > limits.MaxJsonDepth()) {
    return Failed(label + ": nested deeper than " + std::to_string(limits.MaxJsonDepth()) + " levels (at most " +
                  std::to_string(limits.max_earlier) + " earlier incarnations, nested or not)");
  }
  nlohmann::json doc;
  try {
    doc = nlohmann::json::parse(text.begin(), text.end());
  } catch (const nlohmann::json::exception& e) {
    return Failed(label + ": not valid JSON: " + OneLine(e.what()));
  }
  Validator v(label, robot, incarnation, limits);
  AgentCheckpoint c;
  if (!v.Checkpoint(doc, &c)) return Failed(v.error());
  CheckpointLoad r;
  r.checkpoint = std::move(c);
  return r;
}

CheckpointLoad LoadCheckpoint(const std::string& path, RobotId robot, std::uint32_t incarnation,
                              const CheckpointLimits& limits) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::file_status st = fs::status(path, ec);
  if (st.type() == fs::file_type::not_found) {
    CheckpointLoad r;
    r.missing = true;
    r.error = path + ": no such file";
    return r;
  }
  if (ec) return Failed(path + ": " + ec.message());
  if (st.type() == fs::file_type::directory) return Failed(path + ": is a directory, not a checkpoint file");
  if (st.type() != fs::file_type::regular) return Failed(path + ": is not a regular file");
  const std::uintmax_t size = fs::file_size(path, ec);
  if (ec) return Failed(path + ": " + ec.message());
  if (size > limits.max_file_bytes) {
    return Failed(path + ": is " + std::to_string(size) + " bytes, more than the limit of " +
                  std::to_string(limits.max_file_bytes));
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) return Failed(path + ": cannot open for reading");
  std::string text(static_cast<std::size_t>(size), '\0');
  in.read(text.data(), static_cast<std::streamsize>(size));
  if (in.gcount() != static_cast<std::streamsize>(size)) return Failed(path + ": cannot read (it changed while read)");
  if (in.peek() != std::ifstream::traits_type::eof()) return Failed(path + ": grew while it was read");
  return ParseCheckpoint(text, path, robot, incarnation, limits);
}

}  // namespace mapmesh::io
