#pragma once
// The submaps an agent holds, by identity (issue J1): a submap enters once, whoever relayed it.
// The same submap again is a duplicate (counted, ignored); a different submap under an identity
// already held is a conflict (counted and refused: the first one stays), as a robot's submap,
// once closed, never changes. Reads nothing but what it is given; changes nothing but itself.
//
// Pure: no DDS, clocks or random numbers.

#include <cstdint>
#include <map>
#include <set>
#include <span>
#include <utility>
#include <vector>

#include "common/map/submap_codec.h"

namespace mapmesh {

class SubmapBook {
 public:
  enum class Offer { kNew, kDuplicate, kConflict };

  // Offers a decoded submap with the bytes it was decoded from (its identity's content) and its
  // origin's signature over them (secure runs; kept with the bytes, never compared: the bytes
  // alone say whether two submaps are one).
  Offer Add(const WireSubmap& submap, std::span<const std::uint8_t> bytes,
            std::span<const std::uint8_t> signature = {});

  // Drops a held submap (issue R3: a copy its owner disowned); false when none is held.
  bool Remove(const SubmapId& id);

  const WireSubmap* Find(const SubmapId& id) const;
  // The bytes a held submap came in (what a relay sends on); null when not held.
  const std::vector<std::uint8_t>* Bytes(const SubmapId& id) const;
  // The bytes with the signature they came with; null when not held.
  const SubmapBlob* Blob(const SubmapId& id) const;
  // How many of a robot incarnation's submaps are held without a gap from index 0: those a
  // receiver can chain.
  std::uint32_t ChainLength(RobotId robot, std::uint32_t incarnation) const;

  std::size_t size() const { return held_.size(); }
  std::size_t bytes() const { return bytes_; }
  // The bytes held of one robot incarnation's submaps.
  std::size_t ChainBytes(RobotId robot, std::uint32_t incarnation) const;
  int duplicates() const { return duplicates_; }
  int conflicts() const { return conflicts_; }
  // Every submap held, in identity order (robot, incarnation, index).
  std::vector<SubmapId> Ids() const;
  // Every robot incarnation of which a submap is held, with its ChainLength (0 when index 0 is
  // missing), in (robot, incarnation) order.
  std::vector<SubmapChain> Chains() const;
  // The robot incarnations whose submaps share measurements with a later incarnation's of the
  // same robot: their time span (earliest opened_s to latest closed_s of the submaps held, and
  // of `open`'s of that incarnation) overlaps a later one's. An incarnation that replays its
  // robot's stream from the start (lockstep) maps the same scans again and supersedes the
  // earlier; one that takes the stream where it is does not. Joining both would count those
  // measurements twice.
  // With `heard` (the robot incarnations heard themselves: listed by a tick, or a map taken
  // from the robot; issue R3), a later incarnation supersedes an earlier one only when heard;
  // one not heard is the one left out of the overlapping pair (a ghost: submaps relabelled
  // under an incarnation that never ran cannot remove a robot's real chain).
  std::set<std::pair<RobotId, std::uint32_t>> Superseded(
      std::span<const WireSubmap* const> open = {},
      const std::set<std::pair<RobotId, std::uint32_t>>* heard = nullptr) const;

 private:
  struct Entry {
    WireSubmap submap;
    SubmapBlob blob;
  };
  std::map<SubmapId, Entry> held_;
  std::size_t bytes_ = 0;
  std::map<std::pair<RobotId, std::uint32_t>, std::size_t> chain_bytes_;
  int duplicates_ = 0;
  int conflicts_ = 0;
};

}  // namespace mapmesh
