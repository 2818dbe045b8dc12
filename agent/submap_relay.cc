#include "agent/submap_relay.h"

#include "common/map/submap_digest.h"

#include <algorithm>
#include <limits>
#include <tuple>

namespace mapmesh {

void SubmapRelay::CloseOpen(const SubmapId& id) {
  const PeerKey key{id.robot, id.incarnation};
  const auto it = open_.find(key);
  if (it != open_.end() && it->second.id.index == id.index) {
    open_.erase(it);
    open_held_.erase(key);
  }
}

SubmapRelay::Offer SubmapRelay::AddOwn(const WireSubmap& submap, std::span<const std::uint8_t> bytes,
                                       std::span<const std::uint8_t> signature) {
  switch (book_.Add(submap, bytes, signature)) {
    case SubmapBook::Offer::kNew:
      ++counters_.own;
      own_bytes_ += bytes.size();
      digests_[submap.id] = SubmapDigest(bytes);
      return Offer::kNew;
    case SubmapBook::Offer::kDuplicate: return Offer::kDuplicate;
    case SubmapBook::Offer::kConflict: ++counters_.conflicts; return Offer::kConflict;
  }
  return Offer::kConflict;
}

SubmapRelay::Offer SubmapRelay::Add(const WireSubmap& submap, std::span<const std::uint8_t> bytes, double now,
                                    std::span<const std::uint8_t> signature) {
  if (book_.Find(submap.id) == nullptr) {
    if (book_.size() >= options_.max_held || book_.bytes() - own_bytes_ + bytes.size() > options_.max_bytes_held) {
      ++counters_.full;
      return Offer::kFull;
    }
    if (book_.ChainBytes(submap.id.robot, submap.id.incarnation) + bytes.size() > options_.max_chain_bytes) {
      ++counters_.chain_full;
      return Offer::kFull;
    }
  }
  const std::uint64_t digest = SubmapDigest(bytes);
  if (const auto owner = owner_digests_.find({submap.id.robot, submap.id.incarnation}); owner != owner_digests_.end()) {
    const auto said = owner->second.find(submap.id.index);
    if (said != owner->second.end() && said->second != digest) {
      ++counters_.owner_conflicts;
      return Offer::kConflict;
    }
  }
  switch (book_.Add(submap, bytes, signature)) {
    case SubmapBook::Offer::kNew:
      ++counters_.received_new;
      heard_at_[submap.id] = now;
      digests_[submap.id] = digest;
      CloseOpen(submap.id);
      return Offer::kNew;
    case SubmapBook::Offer::kDuplicate:
      ++counters_.duplicates;
      heard_at_[submap.id] = now;
      return Offer::kDuplicate;
    case SubmapBook::Offer::kConflict: ++counters_.conflicts; return Offer::kConflict;
  }
  return Offer::kConflict;
}

SubmapRelay::Offer SubmapRelay::Restore(const WireSubmap& submap, std::span<const std::uint8_t> bytes,
                                        std::span<const std::uint8_t> signature) {
  switch (book_.Add(submap, bytes, signature)) {
    case SubmapBook::Offer::kNew:
      ++counters_.restored;
      digests_[submap.id] = SubmapDigest(bytes);
      return Offer::kNew;
    case SubmapBook::Offer::kDuplicate: ++counters_.duplicates; return Offer::kDuplicate;
    case SubmapBook::Offer::kConflict: ++counters_.conflicts; return Offer::kConflict;
  }
  return Offer::kConflict;
}

void SubmapRelay::OnAdvert(const PeerKey& from, std::span<const SubmapChain> held, double now) {
  Advertised& a = adverts_[from];
  a.count.clear();
  a.open_until.clear();
  a.at = now;
  for (std::size_t i = 0; i < held.size() && i < kMaxChains; ++i) {
    a.count[{held[i].robot, held[i].incarnation}] = held[i].count;
    if (held[i].open_until > 0) a.open_until[{held[i].robot, held[i].incarnation}] = held[i].open_until;
  }
}

void SubmapRelay::Drop(const SubmapId& id) {
  book_.Remove(id);
  digests_.erase(id);
  heard_at_.erase(id);
  sent_at_.erase(id);
}

std::size_t SubmapRelay::OnOwnerAdvert(const PeerKey& owner, std::uint32_t count,
                                       std::span<const std::uint64_t> digests) {
  if (digests.size() > count) return 0;
  std::map<std::uint32_t, std::uint64_t>& said = owner_digests_[owner];
  const std::uint32_t from = count - static_cast<std::uint32_t>(digests.size());
  for (std::uint32_t i = 0; i < digests.size(); ++i) said[from + i] = digests[i];
  // Only the latest kOwnDigests are kept: an older index stays as the owner last said it.
  while (said.size() > kOwnDigests) said.erase(said.begin());
  std::vector<SubmapId> drop;
  for (auto it = digests_.lower_bound({owner.robot, owner.incarnation, from});
       it != digests_.end() && it->first.robot == owner.robot && it->first.incarnation == owner.incarnation; ++it) {
    if (it->first.index >= count) {
      ++counters_.ahead_of_owner;
      drop.push_back(it->first);
    } else if (it->second != digests[it->first.index - from]) {
      ++counters_.owner_conflicts;
      drop.push_back(it->first);
    }
  }
  for (const SubmapId& id : drop) Drop(id);
  return drop.size();
}

std::vector<std::uint64_t> SubmapRelay::OwnDigests(const PeerKey& own) const {
  const std::uint32_t n = book_.ChainLength(own.robot, own.incarnation);
  const std::uint32_t from = n > kOwnDigests ? n - static_cast<std::uint32_t>(kOwnDigests) : 0;
  std::vector<std::uint64_t> out;
  out.reserve(n - from);
  for (std::uint32_t i = from; i < n; ++i) out.push_back(digests_.at({own.robot, own.incarnation, i}));
  return out;
}

std::vector<SubmapChain> SubmapRelay::Advert() const {
  std::vector<SubmapChain> chains = book_.Chains();
  for (const auto& [key, s] : open_) {
    const auto at = std::lower_bound(chains.begin(), chains.end(), key, [](const SubmapChain& c, const PeerKey& k) {
      return std::pair{c.robot, c.incarnation} < std::pair{k.robot, k.incarnation};
    });
    if (at != chains.end() && at->robot == key.robot && at->incarnation == key.incarnation) {
      if (s.id.index >= at->count) at->open_until = s.closed_s;
    } else if (chains.size() < kMaxChains) {  // never at the cost of a closed chain
      chains.insert(at, SubmapChain{key.robot, key.incarnation, 0, s.closed_s});
    }
  }
  if (chains.size() > kMaxChains) chains.resize(kMaxChains);
  return chains;
}

SubmapRelay::Offer SubmapRelay::AddOpen(const WireSubmap& submap, std::span<const std::uint8_t> bytes, double now,
                                        bool relayed, std::span<const std::uint8_t> signature) {
  const PeerKey key{submap.id.robot, submap.id.incarnation};
  const auto held = open_.find(key);
  if (book_.Find(submap.id) != nullptr ||
      (held != open_.end() &&
       std::tie(submap.id.index, submap.closed_s) <= std::tie(held->second.id.index, held->second.closed_s))) {
    return Offer::kDuplicate;
  }
  if (relayed && submap.id.index != book_.ChainLength(submap.id.robot, submap.id.incarnation)) {
    ++counters_.open_gaps;
    return Offer::kGap;
  }
  const std::size_t max_open = options_.max_open > 0 ? options_.max_open : options_.max_held;
  if (held == open_.end() && open_.size() >= max_open) {
    ++counters_.full;
    return Offer::kFull;
  }
  open_[key] = submap;
  OpenHeld& h = open_held_[key];
  h.blob.bytes.assign(bytes.begin(), bytes.end());
  h.blob.signature.assign(signature.begin(), signature.end());
  h.changed_at = now;
  ++counters_.open_taken;
  return Offer::kNew;
}

const std::vector<std::uint8_t>* SubmapRelay::OpenBytes(const PeerKey& key) const {
  const auto it = open_held_.find(key);
  return it == open_held_.end() ? nullptr : &it->second.blob.bytes;
}

std::vector<const SubmapBlob*> SubmapRelay::DueOpen(const std::set<RobotId>& in_range, double now, std::size_t spent) {
  std::vector<std::pair<const PeerKey*, const Advertised*>> listening;
  for (const auto& [key, a] : adverts_) {
    if (in_range.contains(key.robot) && now - a.at <= options_.advert_max_age_s) listening.push_back({&key, &a});
  }
  std::vector<const WireSubmap*> due;
  for (const auto& [key, s] : open_) {
    const OpenHeld& h = open_held_.at(key);
    if (now - h.changed_at < options_.open_silent_after_s || now - h.sent_at < options_.resend_after_s) continue;
    const std::pair chain{key.robot, key.incarnation};
    const bool lacked = std::any_of(listening.begin(), listening.end(), [&](const auto& l) {
      const auto& [peer, a] = l;
      if (peer->robot == key.robot) return false;  // its own robot
      const auto c = a->count.find(chain);
      if ((c == a->count.end() ? 0U : c->second) != s.id.index) return false;  // it cannot chain it, or has it closed
      const auto o = a->open_until.find(chain);
      return o == a->open_until.end() || o->second < s.closed_s;
    });
    if (lacked) due.push_back(&s);
  }
  std::sort(due.begin(), due.end(), [](const WireSubmap* a, const WireSubmap* b) {
    return std::tie(a->id.index, a->id.robot, a->id.incarnation) <
           std::tie(b->id.index, b->id.robot, b->id.incarnation);
  });
  std::vector<const SubmapBlob*> out;
  std::size_t bytes = spent + paid_;
  const bool whole = bytes == 0;
  for (const WireSubmap* s : due) {
    OpenHeld& h = open_held_.at({s->id.robot, s->id.incarnation});
    if (!Spend(h.blob.bytes.size(), bytes, whole && out.empty())) {
      ++counters_.held_back;
      continue;
    }
    out.push_back(&h.blob);
    h.sent_at = now;
    ++counters_.open_relayed;
    counters_.open_bytes_relayed += h.blob.bytes.size();
  }
  return out;
}

bool SubmapRelay::Spend(std::size_t size, std::size_t& spent, bool first) {
  if (!first && spent + size > options_.send_bytes) return false;
  spent += size;
  if (spent > options_.send_bytes) {  // only the first: the rest of its bytes a debt
    debt_ += spent - options_.send_bytes;
    spent = options_.send_bytes;
  }
  return true;
}

std::vector<const SubmapBlob*> SubmapRelay::Due(const std::set<RobotId>& in_range, double now) {
  // A publication pays what earlier ones took beyond their budget first.
  paid_ = std::min(debt_, options_.send_bytes);
  debt_ -= paid_;
  counters_.debt_paid += paid_;
  std::vector<const Advertised*> listening;
  for (const auto& [key, a] : adverts_) {
    if (in_range.contains(key.robot) && now - a.at <= options_.advert_max_age_s) listening.push_back(&a);
  }
  if (listening.empty()) return {};
  // Held submaps some listener lacks and not sent lately, lowest index first.
  std::vector<SubmapId> due;
  for (const SubmapId& id : book_.Ids()) {
    const auto sent = sent_at_.find(id);
    if (sent != sent_at_.end() && now - sent->second < options_.resend_after_s) continue;
    const auto heard = heard_at_.find(id);
    const double heard_at = heard == heard_at_.end() ? -std::numeric_limits<double>::infinity() : heard->second;
    const bool lacked = std::any_of(listening.begin(), listening.end(), [&](const Advertised* a) {
      if (a->at <= heard_at) return false;  // it has not spoken since the submap went round
      const auto c = a->count.find({id.robot, id.incarnation});
      return c == a->count.end() || c->second <= id.index;
    });
    if (lacked) due.push_back(id);
  }
  std::sort(due.begin(), due.end(), [](const SubmapId& a, const SubmapId& b) {
    return std::tie(a.index, a.robot, a.incarnation) < std::tie(b.index, b.robot, b.incarnation);
  });
  std::vector<const SubmapBlob*> out;
  std::size_t bytes = paid_;
  for (const SubmapId& id : due) {
    const SubmapBlob* b = book_.Blob(id);
    if (!Spend(b->bytes.size(), bytes, paid_ == 0 && out.empty())) {
      ++counters_.held_back;
      continue;
    }
    out.push_back(b);
    auto [it, first] = sent_at_.try_emplace(id, now);
    if (!first) {
      ++counters_.sent_again;
      it->second = now;
    }
    ++counters_.sent;
    counters_.bytes_sent += b->bytes.size();
  }
  return out;
}

}  // namespace mapmesh
