#include "common/map/submap_book.h"

#include <algorithm>

namespace mapmesh {

SubmapBook::Offer SubmapBook::Add(const WireSubmap& submap, std::span<const std::uint8_t> bytes,
                                  std::span<const std::uint8_t> signature) {
  const auto it = held_.find(submap.id);
  if (it != held_.end()) {
    const std::vector<std::uint8_t>& held = it->second.blob.bytes;
    const bool same = std::equal(bytes.begin(), bytes.end(), held.begin(), held.end());
    if (same) {
      ++duplicates_;
      return Offer::kDuplicate;
    }
    ++conflicts_;
    return Offer::kConflict;
  }
  held_.emplace(submap.id,
                Entry{submap, SubmapBlob{{bytes.begin(), bytes.end()}, {signature.begin(), signature.end()}}});
  bytes_ += bytes.size();
  chain_bytes_[{submap.id.robot, submap.id.incarnation}] += bytes.size();
  return Offer::kNew;
}

bool SubmapBook::Remove(const SubmapId& id) {
  const auto it = held_.find(id);
  if (it == held_.end()) return false;
  const std::size_t n = it->second.blob.bytes.size();
  bytes_ -= n;
  const auto chain = chain_bytes_.find({id.robot, id.incarnation});
  chain->second -= n;
  if (chain->second == 0) chain_bytes_.erase(chain);
  held_.erase(it);
  return true;
}

std::size_t SubmapBook::ChainBytes(RobotId robot, std::uint32_t incarnation) const {
  const auto it = chain_bytes_.find({robot, incarnation});
  return it == chain_bytes_.end() ? 0 : it->second;
}

const WireSubmap* SubmapBook::Find(const SubmapId& id) const {
  const auto it = held_.find(id);
  return it == held_.end() ? nullptr : &it->second.submap;
}

const std::vector<std::uint8_t>* SubmapBook::Bytes(const SubmapId& id) const {
  const auto it = held_.find(id);
  return it == held_.end() ? nullptr : &it->second.blob.bytes;
}

const SubmapBlob* SubmapBook::Blob(const SubmapId& id) const {
  const auto it = held_.find(id);
  return it == held_.end() ? nullptr : &it->second.blob;
}

std::uint32_t SubmapBook::ChainLength(RobotId robot, std::uint32_t incarnation) const {
  std::uint32_t n = 0;
  for (auto it = held_.lower_bound({robot, incarnation, 0}); it != held_.end(); ++it) {
    if (it->first.robot != robot || it->first.incarnation != incarnation || it->first.index != n) break;
    ++n;
  }
  return n;
}

std::vector<SubmapId> SubmapBook::Ids() const {
  std::vector<SubmapId> out;
  out.reserve(held_.size());
  for (const auto& [id, e] : held_) out.push_back(id);
  return out;
}

std::vector<SubmapChain> SubmapBook::Chains() const {
  std::vector<SubmapChain> out;
  for (auto it = held_.begin(); it != held_.end();) {
    const SubmapId& id = it->first;
    out.push_back({id.robot, id.incarnation, ChainLength(id.robot, id.incarnation)});
    it = held_.upper_bound({id.robot, id.incarnation, UINT32_MAX});
  }
  return out;
}

std::set<std::pair<RobotId, std::uint32_t>> SubmapBook::Superseded(
    std::span<const WireSubmap* const> open, const std::set<std::pair<RobotId, std::uint32_t>>* heard) const {
  using Chain = std::pair<RobotId, std::uint32_t>;
  std::map<Chain, std::pair<double, double>> span;  // (robot, incarnation) -> [from, to], in order
  const auto cover = [&span](const WireSubmap& s) {
    const auto [it, fresh] = span.try_emplace({s.id.robot, s.id.incarnation}, s.opened_s, s.closed_s);
    if (!fresh) {
      it->second.first = std::min(it->second.first, s.opened_s);
      it->second.second = std::max(it->second.second, s.closed_s);
    }
  };
  for (const auto& [id, e] : held_) cover(e.submap);
  for (const WireSubmap* s : open) {
    if (s != nullptr) cover(*s);
  }
  std::set<Chain> out;
  for (auto a = span.begin(); a != span.end(); ++a) {
    for (auto b = std::next(a); b != span.end() && b->first.first == a->first.first; ++b) {
      if (b->second.first < a->second.second && a->second.first < b->second.second) {
        out.insert(heard == nullptr || heard->contains(b->first) ? a->first : b->first);
      }
    }
  }
  return out;
}

}  // namespace mapmesh
