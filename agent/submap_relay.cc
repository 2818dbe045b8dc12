#include "agent/submap_relay.h"

#include <algorithm>
#include <limits>
#include <tuple>

namespace mapmesh {

SubmapRelay::Offer SubmapRelay::AddOwn(const WireSubmap& submap, std::span<const std::uint8_t> bytes) {
  switch (book_.Add(submap, bytes)) {
    case SubmapBook::Offer::kNew: ++counters_.own; return Offer::kNew;
    case SubmapBook::Offer::kDuplicate: return Offer::kDuplicate;
    case SubmapBook::Offer::kConflict: ++counters_.conflicts; return Offer::kConflict;
  }
  return Offer::kConflict;
}

SubmapRelay::Offer SubmapRelay::Add(const WireSubmap& submap, std::span<const std::uint8_t> bytes, double now) {
  if (book_.Find(submap.id) == nullptr && book_.size() >= options_.max_held) {
    ++counters_.full;
    return Offer::kFull;
  }
  switch (book_.Add(submap, bytes)) {
    case SubmapBook::Offer::kNew:
      ++counters_.received_new;
      heard_at_[submap.id] = now;
      return Offer::kNew;
    case SubmapBook::Offer::kDuplicate:
      ++counters_.duplicates;
      heard_at_[submap.id] = now;
      return Offer::kDuplicate;
    case SubmapBook::Offer::kConflict: ++counters_.conflicts; return Offer::kConflict;
  }
  return Offer::kConflict;
}

SubmapRelay::Offer SubmapRelay::Restore(const WireSubmap& submap, std::span<const std::uint8_t> bytes) {
  switch (book_.Add(submap, bytes)) {
    case SubmapBook::Offer::kNew: ++counters_.restored; return Offer::kNew;
    case SubmapBook::Offer::kDuplicate: ++counters_.duplicates; return Offer::kDuplicate;
    case SubmapBook::Offer::kConflict: ++counters_.conflicts; return Offer::kConflict;
  }
  return Offer::kConflict;
}

void SubmapRelay::OnAdvert(const PeerKey& from, std::span<const SubmapChain> held, double now) {
  Advertised& a = adverts_[from];
  a.count.clear();
  a.at = now;
  for (std::size_t i = 0; i < held.size() && i < kMaxChains; ++i) {
    a.count[{held[i].robot, held[i].incarnation}] = held[i].count;
  }
}

std::vector<SubmapChain> SubmapRelay::Advert() const {
  std::vector<SubmapChain> chains = book_.Chains();
  if (chains.size() > kMaxChains) chains.resize(kMaxChains);
  return chains;
}

std::vector<const std::vector<std::uint8_t>*> SubmapRelay::Due(const std::set<RobotId>& in_range, double now) {
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
  std::vector<const std::vector<std::uint8_t>*> out;
  std::size_t bytes = 0;
  for (const SubmapId& id : due) {
    const std::vector<std::uint8_t>* b = book_.Bytes(id);
    if (!out.empty() && bytes + b->size() > options_.send_bytes) {
      ++counters_.held_back;
      continue;
    }
    bytes += b->size();
    out.push_back(b);
    auto [it, first] = sent_at_.try_emplace(id, now);
    if (!first) {
      ++counters_.sent_again;
      it->second = now;
    }
    ++counters_.sent;
    counters_.bytes_sent += b->size();
  }
  return out;
}

}  // namespace mapmesh
