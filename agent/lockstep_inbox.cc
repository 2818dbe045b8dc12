#include "agent/lockstep_inbox.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <utility>

#include "common/map/wire_bytes.h"

namespace mapmesh {

std::string_view ToString(InboxRefusal r) {
  switch (r) {
    case InboxRefusal::kPastTick: return "past_tick";
    case InboxRefusal::kFarTick: return "far_tick";
    case InboxRefusal::kUnknownRobot: return "unknown_robot";
    case InboxRefusal::kIncarnation: return "incarnation";
    case InboxRefusal::kTooManySightings: return "too_many_sightings";
    case InboxRefusal::kPublisherFull: return "publisher_full";
    case InboxRefusal::kUnridden: return "unridden_sighting";
    case InboxRefusal::kReplayed: return "replayed";
    case InboxRefusal::kKeyTaken: return "key_taken";
  }
  return "?";
}

std::size_t LockstepInboxOptions::SightingsPerMap(std::size_t robots, double span_s, double rendezvous_period_s) {
  const double per_peer = 1.0 + std::ceil(std::max(span_s, 0.0) / std::max(rendezvous_period_s, 1e-3));
  const double peers = robots > 1 ? static_cast<double>(robots - 1) : 1.0;
  return static_cast<std::size_t>(std::min(2.0 * peers * per_peer, 1e6));
}

LockstepInbox::LockstepInbox(std::vector<RobotId> robots, RobotId self, const LockstepInboxOptions& options)
    : robots_(std::move(robots)), self_(self), options_(options) {}

bool LockstepInbox::MakeRoomForIncarnation(RobotId robot) {
  std::size_t held = 0;
  auto oldest = held_.end();
  for (auto it = held_.lower_bound({robot, 0}); it != held_.end() && it->first.first == robot; ++it) {
    ++held;
    if (Listed(it->first.first, it->first.second)) continue;
    if (oldest == held_.end() || it->second.last_arrival < oldest->second.last_arrival) oldest = it;
  }
  if (held < options_.incarnations_per_robot) return true;
  if (oldest == held_.end()) return false;
  for (const auto& [t, slot] : oldest->second.ticks) {
    Refuse(InboxRefusal::kIncarnation, static_cast<std::uint32_t>(slot.maps.size()));
    displaced_[{t, robot, oldest->first.second}] = slot.counted;
  }
  while (displaced_.size() > 4 * static_cast<std::size_t>(options_.incarnations_per_robot) * robots_.size()) {
    displaced_.erase(displaced_.begin());  // the lowest ticks: long applied
  }
  held_.erase(oldest);
  return true;
}

void LockstepInbox::OnTick(std::uint32_t index, const std::vector<TickPeer>& peers) {
  if (latest_ && index < *latest_) return;  // an older phase sent again
  if (!latest_ || index > *latest_) listed_.clear();
  for (const TickPeer& p : peers) listed_.insert({p.robot, p.incarnation});
  latest_ = index;
  // Maps of incarnations the tick does not list, for it or earlier ticks, go; before the first
  // exchange, maps of ticks before the latest are history (past).
  for (auto pub = held_.begin(); pub != held_.end();) {
    Held& h = pub->second;
    if (!Listed(pub->first.first, pub->first.second)) {
      for (auto it = h.ticks.begin(); it != h.ticks.end() && it->first <= index;) {
        Refuse(InboxRefusal::kIncarnation, static_cast<std::uint32_t>(it->second.maps.size()));
        std::erase_if(h.arrivals, [&](const MapKey& k) { return std::get<0>(k) == it->first; });
        it = h.ticks.erase(it);
      }
    }
    if (!first_) {
      for (auto it = h.ticks.begin(); it != h.ticks.end() && it->first < index;) {
        if (it->first == 0) {
          ++it;
          continue;
        }
        Refuse(InboxRefusal::kPastTick, static_cast<std::uint32_t>(it->second.maps.size()));
        std::erase_if(h.arrivals, [&](const MapKey& k) { return std::get<0>(k) == it->first; });
        it = h.ticks.erase(it);
      }
    }
    pub = h.ticks.empty() ? held_.erase(pub) : std::next(pub);
  }
}

void LockstepInbox::DropOldest(Held& h) {
  const MapKey oldest = h.arrivals.front();
  h.arrivals.pop_front();
  const auto slot = h.ticks.find(std::get<0>(oldest));
  if (slot == h.ticks.end() || slot->second.maps.erase(oldest) == 0) return;  // (a copy taken back)
  if (slot->second.maps.empty()) h.ticks.erase(slot);
  Refuse(InboxRefusal::kPastTick);
}

LockstepInbox::Offer LockstepInbox::OfferMap(const MapMessage& map, const std::string& writer) {
  const RobotId robot = map.robot_id;
  // The gates, in order; the first that fails is counted.
  std::optional<InboxRefusal> refusal;
  if (std::find(robots_.begin(), robots_.end(), robot) == robots_.end() || robot == self_) {
    refusal = InboxRefusal::kUnknownRobot;
  } else if (map.incarnation == 0) {
    refusal = InboxRefusal::kIncarnation;
  } else if (map.tick != 0 &&
             (map.tick < applied_ || (first_ && map.tick < *first_) || (!first_ && latest_ && map.tick < *latest_))) {
    refusal = InboxRefusal::kPastTick;
  } else if (map.sightings.size() > options_.sightings_per_map) {
    refusal = InboxRefusal::kTooManySightings;
  }
  if (refusal) {
    Refuse(*refusal);
    return {refusal};
  }
  if (!held_.contains({robot, map.incarnation}) && !MakeRoomForIncarnation(robot)) {
    Refuse(InboxRefusal::kIncarnation);
    return {InboxRefusal::kIncarnation};
  }
  Held& h = held_[{robot, map.incarnation}];
  const MapKey key{map.tick, robot, map.incarnation, static_cast<int>(map.kind), map.version};
  auto slot = h.ticks.find(map.tick);
  if (slot != h.ticks.end()) {
    const auto kept = slot->second.maps.find(key);
    if (kept != slot->second.maps.end()) {
      if (SameMap(kept->second.map, map)) return {};  // a duplicate: kept once
      Refuse(InboxRefusal::kKeyTaken);
      return {InboxRefusal::kKeyTaken};
    }
  }
  if (Replayed(map, &h)) {
    Refuse(InboxRefusal::kReplayed);
    return {InboxRefusal::kReplayed};
  }
  if (!first_) {
    // Before the first exchange: the latest arrivals are kept.
    while (h.arrivals.size() >= static_cast<std::size_t>(options_.room_ticks) * options_.maps_per_tick) {
      DropOldest(h);
    }
    h.arrivals.push_back(key);
    slot = h.ticks.find(map.tick);
  } else if (slot == h.ticks.end() && h.ticks.size() >= options_.room_ticks) {
    // The room is full: a nearer tick displaces the farthest, else it is the farthest.
    const auto farthest = std::prev(h.ticks.end());
    if (farthest->first < map.tick) {
      Refuse(InboxRefusal::kFarTick);
      return {InboxRefusal::kFarTick};
    }
    Refuse(InboxRefusal::kFarTick, static_cast<std::uint32_t>(farthest->second.maps.size()));
    h.ticks.erase(farthest);
  }
  if (slot == h.ticks.end()) slot = h.ticks.emplace(map.tick, Slot{}).first;
  Slot& s = slot->second;
  if (s.maps.size() >= options_.maps_per_tick) {
    s.counted = std::min(s.counted + 1, 2 * options_.maps_per_tick);
    if (!first_) h.arrivals.pop_back();
    Refuse(InboxRefusal::kPublisherFull);
    return {InboxRefusal::kPublisherFull};
  }
  ++s.counted;
  h.last_arrival = ++arrivals_;
  Offer out;
  for (const Sighting& r : map.sightings) {
    if (r.robot_id != robot || r.incarnation != map.incarnation || r.tick != map.tick) {
      ++out.foreign_riders;
      continue;
    }
    const SightingKey k{r.tick,  r.robot_id,         r.incarnation, r.stamp, static_cast<int>(r.kind),
                        r.other, r.other_incarnation};
    s.sightings.emplace(k, r);
  }
  Kept kept{map, writer};
  kept.map.sightings.clear();
  s.maps.emplace(key, std::move(kept));
  // Copies of it kept for later ticks (they came first) are taken back, and not waited for.
  for (auto later = std::next(slot); later != h.ticks.end(); ++later) {
    for (auto m = later->second.maps.begin(); m != later->second.maps.end();) {
      const MapMessage& copy = m->second.map;
      if (copy.kind == map.kind && copy.version == map.version && copy.payload == map.payload) {
        later->second.counted -= std::min(later->second.counted, 1u);
        Refuse(InboxRefusal::kReplayed);
        m = later->second.maps.erase(m);
      } else {
        ++m;
      }
    }
  }
  return out;
}

void LockstepInbox::OfferUnridden() { Refuse(InboxRefusal::kUnridden); }

LockstepInbox::Due LockstepInbox::TakeBefore(std::uint32_t tick) {
  if (!first_) {
    first_ = tick;
    for (auto& [pub, h] : held_) h.arrivals.clear();  // from here on the rooms are kept by tick
  }
  applied_ = std::max(applied_, tick);
  std::map<MapKey, Kept> maps;
  std::map<SightingKey, Sighting> sightings;
  for (auto pub = held_.begin(); pub != held_.end();) {
    Held& h = pub->second;
    for (auto it = h.ticks.begin(); it != h.ticks.end() && it->first < tick;) {
      if (it->first != 0 && it->first < *first_) {
        Refuse(InboxRefusal::kPastTick, static_cast<std::uint32_t>(it->second.maps.size()));
      } else {
        maps.merge(it->second.maps);
        sightings.merge(it->second.sightings);
      }
      it = h.ticks.erase(it);
    }
    pub = h.ticks.empty() ? held_.erase(pub) : std::next(pub);
  }
  Due out;
  out.maps.reserve(maps.size());
  out.writers.reserve(maps.size());
  for (auto& [k, kept] : maps) {  // in tick order: a replayed copy that came before its original goes here
    MapMessage& m = kept.map;
    if (Replayed(m, nullptr)) {
      Refuse(InboxRefusal::kReplayed);
      continue;
    }
    auto& taken = taken_[{m.robot_id, m.incarnation, static_cast<int>(m.kind)}];
    taken.emplace_back(m.version, wire::Fnv1a64(m.payload));
    if (taken.size() > kTakenKept) taken.pop_front();
    out.maps.push_back(std::move(m));
    out.writers.push_back(std::move(kept.writer));
  }
  out.sightings.reserve(sightings.size());
  for (auto& [k, s] : sightings) out.sightings.push_back(std::move(s));
  return out;
}

bool LockstepInbox::SameMap(const MapMessage& a, const MapMessage& b) {
  // (Not the sightings: they are kept apart from their map, each once by its own key.)
  return a.stamp == b.stamp && a.origin_stamp == b.origin_stamp && a.payload == b.payload &&
         a.submaps_held == b.submaps_held && a.own_submap_digests == b.own_submap_digests && a.submaps == b.submaps &&
         a.open_submap == b.open_submap && a.open_submap_signature == b.open_submap_signature &&
         a.placements == b.placements && a.open_relayed == b.open_relayed;
}

bool LockstepInbox::Replayed(const MapMessage& map, const Held* held) const {
  const auto taken = taken_.find({map.robot_id, map.incarnation, static_cast<int>(map.kind)});
  if (taken != taken_.end()) {
    const std::pair<std::uint32_t, std::uint64_t> mine{map.version, wire::Fnv1a64(map.payload)};
    if (std::find(taken->second.begin(), taken->second.end(), mine) != taken->second.end()) return true;
  }
  if (held == nullptr) return false;
  for (const auto& [tick, slot] : held->ticks) {
    if (tick >= map.tick) break;
    for (const auto& [key, kept] : slot.maps) {
      const MapMessage& m = kept.map;
      if (m.kind == map.kind && m.version == map.version && m.payload == map.payload) return true;
    }
  }
  return false;
}

std::vector<TickPeer> LockstepInbox::Missing(const ExchangeTick& tick) const {
  std::vector<TickPeer> out;
  for (const TickPeer& p : tick.peers) {
    if (p.robot == self_) continue;
    std::uint32_t here = 0;
    const auto pub = held_.find({p.robot, p.incarnation});
    if (pub != held_.end()) {
      const auto slot = pub->second.ticks.find(tick.index);
      if (slot != pub->second.ticks.end()) here = slot->second.counted;
    }
    const auto displaced = displaced_.find({tick.index, p.robot, p.incarnation});
    if (displaced != displaced_.end()) here += displaced->second;
    if (here < p.messages) out.push_back({p.robot, p.incarnation, here});
  }
  return out;
}

std::uint32_t LockstepInbox::refused_total() const { return std::accumulate(refused_.begin(), refused_.end(), 0u); }

std::size_t LockstepInbox::maps_held() const {
  std::size_t n = 0;
  for (const auto& [pub, h] : held_) {
    for (const auto& [t, s] : h.ticks) n += s.maps.size();
  }
  return n;
}

std::size_t LockstepInbox::sightings_held() const {
  std::size_t n = 0;
  for (const auto& [pub, h] : held_) {
    for (const auto& [t, s] : h.ticks) n += s.sightings.size();
  }
  return n;
}

std::size_t LockstepInbox::MaxMapsHeld() const {
  const std::size_t publishers = robots_.size() - static_cast<std::size_t>(std::find(robots_.begin(), robots_.end(),
                                                                                     self_) != robots_.end());
  return publishers * options_.incarnations_per_robot * options_.room_ticks * options_.maps_per_tick;
}

}  // namespace mapmesh
