#include "common/transport/convert.h"

namespace mapmesh::transport {
namespace {

template <typename Seq, typename Elem>
Seq Borrow(std::vector<Elem>& v) {
  Seq s{};
  s._maximum = static_cast<std::uint32_t>(v.size());
  s._length = static_cast<std::uint32_t>(v.size());
  s._buffer = v.data();
  s._release = false;
  return s;
}

}  // namespace

mapmesh_msg_Odometry ToMsg(const Odometry& v, MsgScratch&) {
  return {v.robot_id, v.seq, v.stamp, v.dt, v.v, v.w, v.steering, v.scans_in_interval, v.sync};
}

Odometry FromMsg(const mapmesh_msg_Odometry& m) {
  return {m.robot_id, m.seq, m.stamp, m.dt, m.v, m.w, m.steering, m.scans_in_interval, m.sync};
}

mapmesh_msg_Scan ToMsg(const Scan& v, MsgScratch& scratch) {
  scratch.obs.clear();
  for (const Observation& o : v.obs) {
    scratch.obs.push_back({static_cast<float>(o.range), static_cast<float>(o.bearing), o.signature,
                           static_cast<std::uint8_t>(o.kind)});
  }
  mapmesh_msg_Scan m{};
  m.robot_id = v.robot_id;
  m.seq = v.seq;
  m.stamp = v.stamp;
  m.obs = Borrow<dds_sequence_mapmesh_msg_Observation>(scratch.obs);
  return m;
}

Scan FromMsg(const mapmesh_msg_Scan& m) {
  Scan s;
  s.robot_id = m.robot_id;
  s.seq = m.seq;
  s.stamp = m.stamp;
  s.obs.reserve(m.obs._length);
  for (std::uint32_t i = 0; i < m.obs._length; ++i) {
    const auto& o = m.obs._buffer[i];
    s.obs.push_back({o.range, o.bearing, o.signature,
                     o.kind == 1 ? ObservationKind::kRobot : ObservationKind::kLandmark});
  }
  return s;
}

mapmesh_msg_RadioLinks ToMsg(const RadioLinks& v, MsgScratch& scratch) {
  scratch.links.clear();
  for (const Link& l : v.links) scratch.links.push_back({l.a, l.b});
  mapmesh_msg_RadioLinks m{};
  m.stamp = v.stamp;
  m.links = Borrow<dds_sequence_mapmesh_msg_Link>(scratch.links);
  return m;
}

RadioLinks FromMsg(const mapmesh_msg_RadioLinks& m) {
  RadioLinks r;
  r.stamp = m.stamp;
  for (std::uint32_t i = 0; i < m.links._length; ++i) {
    r.links.push_back({m.links._buffer[i].a, m.links._buffer[i].b});
  }
  return r;
}

mapmesh_msg_GroundTruth ToMsg(const GroundTruth& v, MsgScratch&) { return {v.robot_id, v.stamp, v.x, v.y, v.theta}; }

GroundTruth FromMsg(const mapmesh_msg_GroundTruth& m) { return {m.robot_id, m.stamp, m.x, m.y, m.theta}; }

mapmesh_msg_MapMessage ToMsg(const MapMessage& v, MsgScratch& scratch) {
  mapmesh_msg_MapMessage m{};
  m.robot_id = v.robot_id;
  m.kind = static_cast<std::uint8_t>(v.kind);
  m.incarnation = v.incarnation;
  m.version = v.version;
  m.stamp = v.stamp;
  m.origin_stamp = v.origin_stamp;
  m.tick = v.tick;
  m.payload._maximum = static_cast<std::uint32_t>(v.payload.size());
  m.payload._length = static_cast<std::uint32_t>(v.payload.size());
  m.payload._buffer = const_cast<std::uint8_t*>(v.payload.data());
  m.payload._release = false;
  scratch.sightings.clear();
  for (const Sighting& s : v.sightings) scratch.sightings.push_back(ToMsg(s, scratch));
  m.sightings._maximum = static_cast<std::uint32_t>(scratch.sightings.size());
  m.sightings._length = m.sightings._maximum;
  m.sightings._buffer = scratch.sightings.data();
  m.sightings._release = false;
  scratch.chains.clear();
  for (const SubmapChain& c : v.submaps_held) scratch.chains.push_back({c.robot, c.incarnation, c.count, c.open_until});
  m.submaps_held._maximum = static_cast<std::uint32_t>(scratch.chains.size());
  m.submaps_held._length = m.submaps_held._maximum;
  m.submaps_held._buffer = scratch.chains.data();
  m.submaps_held._release = false;
  m.own_submap_digests._maximum = static_cast<std::uint32_t>(v.own_submap_digests.size());
  m.own_submap_digests._length = m.own_submap_digests._maximum;
  m.own_submap_digests._buffer = const_cast<std::uint64_t*>(v.own_submap_digests.data());
  m.own_submap_digests._release = false;
  // Both blob sequences borrow from one scratch vector, sized first so that it never moves.
  scratch.blobs.clear();
  scratch.blobs.reserve(v.submaps.size() + v.open_relayed.size());
  const auto borrow = [](const std::vector<std::uint8_t>& from, dds_sequence_octet& to) {
    to._maximum = static_cast<std::uint32_t>(from.size());
    to._length = to._maximum;
    to._buffer = const_cast<std::uint8_t*>(from.data());
    to._release = false;
  };
  const auto blobs = [&scratch, &borrow](const std::vector<SubmapBlob>& from, dds_sequence_mapmesh_msg_SubmapBlob& to) {
    const std::size_t first = scratch.blobs.size();
    for (const SubmapBlob& b : from) {
      mapmesh_msg_SubmapBlob blob{};
      borrow(b.bytes, blob.bytes);
      borrow(b.signature, blob.signature);
      scratch.blobs.push_back(blob);
    }
    to._maximum = static_cast<std::uint32_t>(from.size());
    to._length = to._maximum;
    to._buffer = from.empty() ? nullptr : scratch.blobs.data() + first;
    to._release = false;
  };
  blobs(v.submaps, m.submaps);
  blobs(v.open_relayed, m.open_relayed);
  borrow(v.open_submap, m.open_submap);
  borrow(v.open_submap_signature, m.open_submap_signature);
  scratch.placements.clear();
  for (const ChainPlacement& c : v.placements)
    scratch.placements.push_back({c.robot, c.incarnation, c.x, c.y, c.theta});
  m.placements._maximum = static_cast<std::uint32_t>(scratch.placements.size());
  m.placements._length = m.placements._maximum;
  m.placements._buffer = scratch.placements.data();
  m.placements._release = false;
  return m;
}

MapMessage FromMsg(const mapmesh_msg_MapMessage& m) {
  MapMessage v;
  v.robot_id = m.robot_id;
  v.kind = m.kind == 1 ? MapKind::kGlobal : MapKind::kLocal;
  v.incarnation = m.incarnation;
  v.version = m.version;
  v.stamp = m.stamp;
  v.origin_stamp = m.origin_stamp;
  v.tick = m.tick;
  if (m.payload._length > 0) v.payload.assign(m.payload._buffer, m.payload._buffer + m.payload._length);
  v.sightings.reserve(m.sightings._length);
  for (std::uint32_t i = 0; i < m.sightings._length; ++i) v.sightings.push_back(FromMsg(m.sightings._buffer[i]));
  v.submaps_held.reserve(m.submaps_held._length);
  for (std::uint32_t i = 0; i < m.submaps_held._length; ++i) {
    const mapmesh_msg_SubmapChain& c = m.submaps_held._buffer[i];
    v.submaps_held.push_back({c.robot, c.incarnation, c.count, c.open_until});
  }
  if (m.own_submap_digests._length > 0) {
    v.own_submap_digests.assign(m.own_submap_digests._buffer,
                                m.own_submap_digests._buffer + m.own_submap_digests._length);
  }
  const auto copy = [](const dds_sequence_octet& from) {
    return from._length == 0 ? std::vector<std::uint8_t>{}
                             : std::vector<std::uint8_t>(from._buffer, from._buffer + from._length);
  };
  v.submaps.reserve(m.submaps._length);
  for (std::uint32_t i = 0; i < m.submaps._length; ++i)
    v.submaps.push_back({copy(m.submaps._buffer[i].bytes), copy(m.submaps._buffer[i].signature)});
  v.open_submap = copy(m.open_submap);
  v.open_submap_signature = copy(m.open_submap_signature);
  v.open_relayed.reserve(m.open_relayed._length);
  for (std::uint32_t i = 0; i < m.open_relayed._length; ++i)
    v.open_relayed.push_back({copy(m.open_relayed._buffer[i].bytes), copy(m.open_relayed._buffer[i].signature)});
  v.placements.reserve(m.placements._length);
  for (std::uint32_t i = 0; i < m.placements._length; ++i) {
    const mapmesh_msg_ChainPlacement& c = m.placements._buffer[i];
    v.placements.push_back({c.robot, c.incarnation, c.x, c.y, c.theta});
  }
  return v;
}

mapmesh_msg_AgentStatus ToMsg(const AgentStatus& v, MsgScratch& scratch) {
  scratch.ids.assign(v.peers_aligned.begin(), v.peers_aligned.end());
  scratch.ids2.assign(v.peers_stale.begin(), v.peers_stale.end());
  mapmesh_msg_AgentStatus m{};
  m.robot_id = v.robot_id;
  m.incarnation = v.incarnation;
  m.processed_until = v.processed_until;
  m.odom_processed = v.odom_processed;
  m.scans_processed = v.scans_processed;
  m.local_landmarks = v.local_landmarks;
  m.global_landmarks = v.global_landmarks;
  m.maps_received = v.maps_received;
  m.maps_dropped = v.maps_dropped;
  m.bytes_sent = v.bytes_sent;
  m.bytes_received = v.bytes_received;
  m.peers_aligned = Borrow<dds_sequence_uint32>(scratch.ids);
  m.peers_stale = Borrow<dds_sequence_uint32>(scratch.ids2);
  m.tick_done = v.tick_done;
  m.tick_published = v.tick_published;
  m.tick_delivered = v.tick_delivered;
  return m;
}

AgentStatus FromMsg(const mapmesh_msg_AgentStatus& m) {
  AgentStatus s;
  s.robot_id = m.robot_id;
  s.incarnation = m.incarnation;
  s.processed_until = m.processed_until;
  s.odom_processed = m.odom_processed;
  s.scans_processed = m.scans_processed;
  s.local_landmarks = m.local_landmarks;
  s.global_landmarks = m.global_landmarks;
  s.maps_received = m.maps_received;
  s.maps_dropped = m.maps_dropped;
  s.bytes_sent = m.bytes_sent;
  s.bytes_received = m.bytes_received;
  s.peers_aligned.assign(m.peers_aligned._buffer, m.peers_aligned._buffer + m.peers_aligned._length);
  s.peers_stale.assign(m.peers_stale._buffer, m.peers_stale._buffer + m.peers_stale._length);
  s.tick_done = m.tick_done;
  s.tick_published = m.tick_published;
  s.tick_delivered = m.tick_delivered;
  return s;
}

mapmesh_msg_Sighting ToMsg(const Sighting& v, MsgScratch&) {
  mapmesh_msg_Sighting m{};
  m.robot_id = v.robot_id;
  m.incarnation = v.incarnation;
  m.kind = static_cast<std::uint8_t>(v.kind);
  m.other = v.other;
  m.other_incarnation = v.other_incarnation;
  m.stamp = v.stamp;
  m.x = v.x;
  m.y = v.y;
  m.theta = v.theta;
  for (std::size_t i = 0; i < v.cov.size(); ++i) m.cov[i] = v.cov[i];
  m.range = v.range;
  m.bearing = v.bearing;
  m.sigma_range = v.sigma_range;
  m.sigma_bearing = v.sigma_bearing;
  m.tick = v.tick;
  return m;
}

Sighting FromMsg(const mapmesh_msg_Sighting& m) {
  Sighting v;
  v.robot_id = m.robot_id;
  v.incarnation = m.incarnation;
  v.kind = m.kind == 1 ? SightingKind::kAnswer : SightingKind::kSighting;
  v.other = m.other;
  v.other_incarnation = m.other_incarnation;
  v.stamp = m.stamp;
  v.x = m.x;
  v.y = m.y;
  v.theta = m.theta;
  for (std::size_t i = 0; i < v.cov.size(); ++i) v.cov[i] = m.cov[i];
  v.range = m.range;
  v.bearing = m.bearing;
  v.sigma_range = m.sigma_range;
  v.sigma_bearing = m.sigma_bearing;
  v.tick = m.tick;
  return v;
}

mapmesh_msg_ExchangeTick ToMsg(const ExchangeTick& v, MsgScratch& scratch) {
  scratch.tick_peers.clear();
  for (const TickPeer& p : v.peers) scratch.tick_peers.push_back({p.robot, p.incarnation, p.messages});
  mapmesh_msg_ExchangeTick m{};
  m.index = v.index;
  m.stamp = v.stamp;
  m.phase = static_cast<std::uint8_t>(v.phase);
  m.links = ToMsg(v.links, scratch);
  m.peers = Borrow<dds_sequence_mapmesh_msg_TickPeer>(scratch.tick_peers);
  return m;
}

ExchangeTick FromMsg(const mapmesh_msg_ExchangeTick& m) {
  ExchangeTick v;
  v.index = m.index;
  v.stamp = m.stamp;
  v.phase = m.phase == 1 ? TickPhase::kDeliver : TickPhase::kExchange;
  v.links = FromMsg(m.links);
  for (std::uint32_t i = 0; i < m.peers._length; ++i) {
    const auto& p = m.peers._buffer[i];
    v.peers.push_back({p.robot, p.incarnation, p.messages});
  }
  return v;
}

}  // namespace mapmesh::transport
