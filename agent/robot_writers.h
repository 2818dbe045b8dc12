#pragma once
// Which DDS writer speaks for each robot incarnation (issue R3): the one whose map was taken
// first. A robot's agent publishes its maps from one writer for the life of its process (one
// incarnation), and the writer's GUID is a fact of the transport, not a claim in the message.
// So once a map of (robot, incarnation) has been taken from a writer, a map claiming that
// robot incarnation from any other writer is refused (MapRefusal::kOtherWriter): a participant
// that copies a robot's maps and writes the robot's next map key before it (mapmesh-inject
// forged_relay) no longer takes that key, in a plain run or under --secure with another
// agent's credentials.
//
// What it does not stop: a writer that speaks for a robot incarnation before the robot's own
// first map is taken takes its place (trust on first use, as FeederSource does for the feeder;
// docs/SECURITY.md). A restarted robot is a new incarnation with a new writer, bound anew.
// An empty writer is unknown (a test, a map replayed from a checkpoint): never refused, never
// bound.
//
// Pure: the caller hands in the writer's GUID.

#include <cstdint>
#include <deque>
#include <map>
#include <string>
#include <utility>

#include "common/types/messages.h"

namespace mapmesh {

class RobotWriters {
 public:
  // Robot incarnations bound per robot: the oldest bound goes beyond this (a genuine robot
  // needs one, two across a restart).
  static constexpr std::size_t kIncarnationsPerRobot = 4;

  // Whether a map claiming (robot, incarnation) from `writer` may be taken.
  bool Admits(RobotId robot, std::uint32_t incarnation, const std::string& writer) const;
  // A map of (robot, incarnation) from `writer` was taken: the first binds it.
  void Bind(RobotId robot, std::uint32_t incarnation, const std::string& writer);
  // The writer bound to (robot, incarnation); nullptr if none.
  const std::string* Bound(RobotId robot, std::uint32_t incarnation) const;
  std::size_t size() const { return writers_.size(); }

 private:
  std::map<std::pair<RobotId, std::uint32_t>, std::string> writers_;
  std::map<RobotId, std::deque<std::uint32_t>> order_;  // per robot, its incarnations bound, oldest first
};

}  // namespace mapmesh
