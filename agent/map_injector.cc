#include "agent/map_injector.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <sstream>
#include <tuple>

#include "common/check.h"
#include "common/map/map_codec.h"
#include "common/map/map_faults.h"

namespace mapmesh {

std::vector<std::string> AllInjectCases() {
  std::vector<std::string> cases;
  for (int i = 0; i < kPayloadFaultCount; ++i) cases.emplace_back(ToString(static_cast<PayloadFault>(i)));
  for (const char* c :
       {kInjectStaleVersion, kInjectUnknownSender, kInjectShuffled, kInjectOdometryStamp, kInjectFarReading,
        kInjectLinksStamp, kInjectLinksAhead, kInjectVersionJump, kInjectHugeMap, kInjectTickFlood,
        kInjectForgedSubmaps, kInjectGhostIncarnation, kInjectForgedRelay, kInjectHugeSubmaps}) {
    cases.emplace_back(c);
  }
  return cases;
}

std::optional<std::vector<std::string>> ParseInjectCases(const std::string& text) {
  const std::vector<std::string> all = AllInjectCases();
  if (text == "all") return all;
  std::vector<std::string> cases;
  std::stringstream in(text);
  for (std::string c; std::getline(in, c, ',');) {
    if (std::find(all.begin(), all.end(), c) == all.end()) return std::nullopt;
    if (std::find(cases.begin(), cases.end(), c) == cases.end()) cases.push_back(c);
  }
  if (cases.empty()) return std::nullopt;
  return cases;
}

MapInjector::MapInjector(std::vector<RobotId> robots, std::vector<std::string> cases, RobotId unknown_id,
                         std::uint64_t seed)
    : robots_(std::move(robots)), cases_(std::move(cases)), unknown_id_(unknown_id), rng_(seed) {
  MAPMESH_CHECK(!robots_.empty() && !cases_.empty(), "MapInjector needs robots and cases");
  MAPMESH_CHECK(std::find(robots_.begin(), robots_.end(), unknown_id_) == robots_.end(),
                "the unknown sender id is a robot of the run");
}

void MapInjector::OnMap(const MapMessage& m) {
  if (m.kind != MapKind::kLocal || injected_.count(Key(m)) ||
      std::find(robots_.begin(), robots_.end(), m.robot_id) == robots_.end()) {
    return;
  }
  ++maps_heard_[m.robot_id];
  for (const SubmapBlob& blob : m.submaps) {
    SubmapDecodeResult s = DecodeSubmap(blob.bytes);
    if (!s.ok() || s.submap.id.robot != m.robot_id || s.submap.id.incarnation != m.incarnation) continue;
    const auto held = last_closed_.find(m.robot_id);
    if (held == last_closed_.end() || std::tie(held->second.id.incarnation, held->second.id.index) <
                                          std::tie(s.submap.id.incarnation, s.submap.id.index)) {
      last_closed_[m.robot_id] = std::move(s.submap);
    }
  }
  const auto it = heard_.find(m.robot_id);
  if (it != heard_.end() && it->second.msg.incarnation == m.incarnation && m.version <= it->second.msg.version) return;
  MapDecodeResult d = DecodeMap(m.payload);
  if (!d.ok()) return;
  heard_[m.robot_id] = {m, std::move(d.map)};
}

std::map<RobotId, MapInjector::HeardFrom> MapInjector::heard_from() const {
  std::map<RobotId, HeardFrom> out;
  for (const auto& [robot, n] : maps_heard_) out[robot].maps = n;
  for (const auto& [robot, s] : last_closed_) out[robot].closed_submap = true;
  return out;
}

void MapInjector::OnStatus(const AgentStatus& s) {
  aligned_.insert(s.peers_aligned.begin(), s.peers_aligned.end());
  processed_until_[s.robot_id] = std::max(processed_until_[s.robot_id], s.processed_until);
}

void MapInjector::OnTick(const ExchangeTick& t) {
  listed_.clear();
  for (const TickPeer& p : t.peers) listed_[p.robot] = p.incarnation;
}

std::optional<InjectedMessage> MapInjector::Next() {
  const std::size_t slots = cases_.size() * robots_.size();
  for (std::size_t k = 0; k < slots; ++k) {
    const std::size_t t = tick_++;
    const std::string& c = cases_[(t / robots_.size()) % cases_.size()];
    const RobotId robot = robots_[t % robots_.size()];
    if (std::optional<InjectedMessage> m = Make(c, robot)) {
      if (const MapMessage* map = std::get_if<MapMessage>(&*m)) {
        injected_.insert(Key(*map));
        if (!IsHonest(*map)) ++sent_[c][map->robot_id];
      } else {
        ++sent_[c][robot];
      }
      return m;
    }
  }
  return std::nullopt;
}

std::optional<InjectedMessage> MapInjector::MakeHostile(const std::string& c, RobotId target) {
  const auto reported = processed_until_.find(target);
  if (c == kInjectOdometryStamp) {
    Odometry o;
    o.robot_id = target;
    o.seq = 0xFFFFFF00u;
    o.stamp = 1e9;
    o.dt = 0.1;
    o.v = 1.0;
    return o;
  }
  if (c == kInjectFarReading) {
    if (reported == processed_until_.end()) return std::nullopt;  // its time is not known yet
    Scan s;
    s.robot_id = target;
    s.seq = kInjectFarReadingSeq;
    s.stamp = reported->second + 0.05;
    s.obs.push_back({30000.0, 0.0, -1, ObservationKind::kLandmark});
    return s;
  }
  if (c == kInjectLinksStamp) return RadioLinks{1e300, {}};
  if (c == kInjectLinksAhead) {
    if (reported == processed_until_.end()) return std::nullopt;
    RadioLinks everyone{reported->second + kInjectLinksAheadS, {}};
    for (std::size_t i = 0; i < robots_.size(); ++i) {
      for (std::size_t j = i + 1; j < robots_.size(); ++j) everyone.links.push_back({robots_[i], robots_[j]});
    }
    return everyone;
  }
  const auto it = heard_.find(target);
  if (c == kInjectVersionJump) {
    if (it == heard_.end()) return std::nullopt;
    MapMessage m = it->second.msg;
    m.version = 0xFFFFFFF0u;
    return m;
  }
  if (c == kInjectTickFlood) {
    if (flood_payload_.empty()) flood_payload_ = EncodeMap(RandomMap(5));
    const std::uint32_t turn = flood_version_++;
    MapMessage m;
    m.kind = MapKind::kLocal;
    m.version = 0x40000000u + turn;  // distinct, so that none is taken for a copy of another
    m.payload = flood_payload_;
    m.robot_id = turn % 3 == 0 ? unknown_id_ : target;
    m.incarnation = it != heard_.end() && m.robot_id == target ? it->second.msg.incarnation : 1u;
    m.tick = 0xFFFFFFFFu;
    // The second turn: the robot at one of eight ticks far ahead, without riders (its room fills);
    // the third: at the tick after the robot's latest map's (before one is heard, far ahead).
    if (turn % 3 == 1) m.tick = 0xFFFFFFFFu - flood_far_[target]++ % 8;
    if (turn % 3 == 2 && it != heard_.end() && it->second.msg.tick != 0) m.tick = it->second.msg.tick + 1;
    if (it != heard_.end()) m.stamp = it->second.msg.stamp;
    if (turn % 3 == 1) return m;
    m.sightings.resize(kInjectFloodSightings);
    for (std::size_t i = 0; i < m.sightings.size(); ++i) {
      Sighting& s = m.sightings[i];
      s.robot_id = m.robot_id;
      s.incarnation = m.incarnation;
      s.tick = m.tick;
      s.other = target;
      s.stamp = m.stamp + 1e-3 * static_cast<double>(i);
      s.cov = {0.01, 0.0, 0.0, 0.01, 0.0, 0.001};
      s.range = 2.0;
      s.sigma_range = 0.1;
      s.sigma_bearing = 0.01;
    }
    return m;
  }
  if (c == kInjectForgedSubmaps || c == kInjectGhostIncarnation || c == kInjectForgedRelay) {
    const auto last = last_closed_.find(target);
    if (last == last_closed_.end()) return std::nullopt;
    std::vector<std::vector<std::uint8_t>> submaps;
    if (c != kInjectGhostIncarnation) {
      std::uniform_real_distribution<double> shift(3.0, 15.0), angle(-std::numbers::pi, std::numbers::pi);
      for (std::uint32_t k = 1; k <= kInjectForgedSubmapCount; ++k) {
        WireSubmap s = last->second;
        s.id.index += k;
        for (Eigen::Index j = 3; j + 1 < s.x.size(); j += 2) {
          const double r = shift(rng_), a = angle(rng_);
          s.x(j) += r * std::cos(a);
          s.x(j + 1) += r * std::sin(a);
        }
        submaps.push_back(EncodeSubmap(s));
      }
    } else {
      WireSubmap ghost = last->second;
      ghost.id.incarnation = kInjectGhostIncarnationId;
      submaps.push_back(EncodeSubmap(ghost));
      ghost.id.incarnation = kInjectGhostIncarnationId + 1;
      ghost.opened_s = -1e9;
      submaps.push_back(EncodeSubmap(ghost));
    }
    return Carry(target, std::move(submaps), c == kInjectForgedRelay);
  }
  if (c == kInjectHugeSubmaps) {
    const auto last = last_closed_.find(target);
    if (last == last_closed_.end()) return std::nullopt;
    std::uint32_t& index = huge_index_.try_emplace(target, last->second.id.index + kInjectHugeSubmapsFrom)
                               .first->second;
    std::vector<std::vector<std::uint8_t>> submaps;
    for (std::uint32_t k = 0; k < kInjectHugeSubmapCount; ++k) submaps.push_back(HugeSubmap(last->second, index + k));
    std::optional<InjectedMessage> m = Carry(target, std::move(submaps), /*ahead=*/true);
    if (m) index += kInjectHugeSubmapCount;  // new identities each time
    return m;
  }
  // huge_map
  if (huge_turns_++ % kInjectHugeEvery != 0) return std::nullopt;
  if (huge_payload_.empty()) huge_payload_ = EncodeMap(RandomMap(static_cast<int>(kMapCodecMaxLandmarks)));
  MapMessage m;
  m.robot_id = target;
  m.kind = MapKind::kLocal;
  m.incarnation = kInjectHugeIncarnation;
  m.version = ++huge_version_[target];
  if (it != heard_.end()) m.stamp = it->second.msg.stamp;
  m.payload = huge_payload_;
  return m;
}

std::optional<InjectedMessage> MapInjector::Carry(RobotId robot, std::vector<std::vector<std::uint8_t>> submaps,
                                                  bool ahead) const {
  const auto at = std::find(robots_.begin(), robots_.end(), robot);
  RobotId carrier = std::next(at) == robots_.end() ? robots_.front() : *std::next(at);
  if (ahead && act_as_) carrier = *act_as_;
  auto it = heard_.find(carrier);
  const auto listed = listed_.find(carrier);
  const bool as_relay = ahead && act_as_ && it == heard_.end();
  if (as_relay) it = heard_.find(robot);  // the forged robot's own latest, under the relay's id
  if (carrier == robot || it == heard_.end() || (as_relay && listed == listed_.end())) return std::nullopt;
  MapMessage m = it->second.msg;  // the carrier's latest: its version taken already, so stale
  if (as_relay) {
    m.robot_id = carrier;
    m.incarnation = listed->second;
  }
  // Ahead: two ticks and versions on, so that it is there before the robot's own of that tick.
  if (m.tick != 0) m.tick += ahead ? 2 : 1;
  if (ahead) m.version += 2;
  m.submaps.clear();
  for (std::vector<std::uint8_t>& bytes : submaps) {
    std::vector<std::uint8_t> signature = sign_ ? sign_(bytes) : std::vector<std::uint8_t>{};
    m.submaps.push_back({std::move(bytes), std::move(signature)});
  }
  m.open_submap.clear();
  m.open_submap_signature.clear();
  m.open_relayed.clear();
  m.sightings.clear();
  return m;
}

std::vector<std::uint8_t> MapInjector::HugeSubmap(const WireSubmap& like, std::uint32_t index) {
  const Eigen::Index near = (like.x.size() - 3) / 2;
  std::uniform_real_distribution<double> spread(-2.0, 2.0), wide(-20.0, 20.0);
  WireSubmap s;
  s.id = like.id;
  s.id.index = index;
  s.opened_s = like.opened_s;
  s.closed_s = like.closed_s;
  const Eigen::Index n = kSubmapCodecMaxLandmarks;
  s.x = Eigen::VectorXd::Zero(3 + 2 * n);
  s.x.head(3) = like.x.head(3);
  for (Eigen::Index i = 0; i < n; ++i) {
    s.keys.push_back(static_cast<std::uint32_t>(1000000 + i));
    const Eigen::Index j = 3 + 2 * (near > 0 ? i % near : 0);
    s.x(3 + 2 * i) = near > 0 ? like.x(j) + spread(rng_) : wide(rng_);
    s.x(4 + 2 * i) = near > 0 ? like.x(j + 1) + spread(rng_) : wide(rng_);
  }
  const bool set = s.SetCovariance(0.01 * Eigen::MatrixXd::Identity(s.x.size(), s.x.size()));
  MAPMESH_CHECK(set, "a diagonal covariance is positive definite");
  std::vector<std::uint8_t> bytes = EncodeSubmap(s);
  MAPMESH_CHECK(!bytes.empty(), "huge_submaps made a submap its codec refuses");
  return bytes;
}

LandmarkMap MapInjector::RandomMap(int n) {
  std::uniform_real_distribution<double> u(0.0, 50.0);
  LandmarkMap m;
  for (int i = 0; i < n; ++i) {
    Landmark l;
    l.id = static_cast<std::uint32_t>(i + 1);
    l.mean = {u(rng_), u(rng_)};
    l.cov = Eigen::Matrix2d::Identity() * 0.01;
    m.landmarks.push_back(l);
  }
  return m;
}

std::optional<InjectedMessage> MapInjector::Make(const std::string& c, RobotId sender) {
  if (c == kInjectOdometryStamp || c == kInjectFarReading || c == kInjectLinksStamp || c == kInjectLinksAhead ||
      c == kInjectVersionJump || c == kInjectHugeMap || c == kInjectTickFlood || c == kInjectForgedSubmaps ||
      c == kInjectGhostIncarnation || c == kInjectForgedRelay || c == kInjectHugeSubmaps) {
    return MakeHostile(c, sender);
  }
  MapMessage m;
  m.robot_id = sender;
  const auto it = heard_.find(sender);
  const Heard* h = it == heard_.end() ? nullptr : &it->second;
  if (h) {
    m.incarnation = h->msg.incarnation;
    m.stamp = h->msg.stamp;
    m.origin_stamp = h->msg.origin_stamp;
  }
  if (const std::optional<PayloadFault> f = PayloadFaultFromString(c)) {
    m.incarnation = kInjectPayloadIncarnation;
    m.kind = MapKind::kGlobal;
    m.payload = CorruptPayload(EncodeMap(RandomMap(8)), *f);
    return m;
  }
  m.kind = MapKind::kLocal;
  if (c == kInjectUnknownSender) {
    m.robot_id = unknown_id_;
    m.incarnation = 1;
    m.version = ++unknown_version_;
    m.payload = EncodeMap(RandomMap(30));
    return m;
  }
  if (!h || h->msg.version < 2) return std::nullopt;
  if (c == kInjectStaleVersion) {
    m.version = h->msg.version - 1;
    m.payload = h->msg.payload;
    return m;
  }
  // shuffled: a faulty peer in the sender's frame, two honest maps (aligned and confirmed)
  // then two shuffled ones (refused by verification, which drops the alignment), and again.
  if (!aligned_.count(sender) || h->map.size() < 6) return std::nullopt;
  m.incarnation = kInjectFaultyIncarnation;
  m.version = ++faulty_version_[sender];
  if (IsHonest(m)) {
    m.payload = h->msg.payload;
    ++honest_sent_;
  } else {
    m.payload = EncodeMap(ShuffleCoordinates(h->map, rng_));
  }
  return m;
}

}  // namespace mapmesh
