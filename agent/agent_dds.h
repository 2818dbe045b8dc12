#pragma once
// The agent process's DDS side (mapmesh-agent): its writers (AgentOutput), and its readers with
// the checks on who sent what, feeding the node. Everything the readers hold goes into the node
// at each Pump; samples claiming a robot from a writer outside that robot's partition, and link
// tables and ticks not from the run's feeder, are refused and counted (ShellCounts). Exchange
// ticks wait here, in order, until the node can carry them out.

#include <chrono>
#include <deque>
#include <map>
#include <optional>

#include "agent/agent_node.h"
#include "agent/agent_outputs.h"
#include "common/transport/feeder_source.h"
#include "common/transport/oversize_counter.h"
#include "common/transport/topics.h"
#include "common/transport/typed.h"

namespace mapmesh {

// Sends the agent's messages through DDS writers. The status is best-effort, and the feeder's
// lockstep barrier waits for it: each status the node publishes is sent once more a moment
// later (with what the node then knows), so that one lost datagram on a lossy link does not
// hold the barrier until the next beat.
class DdsOutput : public AgentOutput {
 public:
  using Clock = std::chrono::steady_clock;
  static constexpr auto kStatusRepeat = std::chrono::milliseconds(30);

  DdsOutput(const transport::Participant& p, double lease_s, RobotId self, bool lockstep);
  void PublishMap(const MapMessage& msg) override { maps_.Write(msg); }
  void PublishStatus(const AgentStatus& status) override;
  void PublishSighting(const Sighting& s) override {
    if (sightings_) sightings_->Write(s);
  }
  // A status sent on the launcher's beat or as a repeat: no repeat of its own.
  void SendStatus(const AgentStatus& status) { status_.Write(status); }
  // When the last status published by the node is due to be repeated (nullopt: none is).
  std::optional<Clock::time_point> RepeatDue() const { return repeat_at_; }
  void RepeatDone() { repeat_at_.reset(); }

 private:
  std::optional<Clock::time_point> repeat_at_;
  transport::Writer<MapMessage> maps_;
  transport::Writer<AgentStatus> status_;
  std::optional<transport::Writer<Sighting>> sightings_;
};

class AgentReaders {
 public:
  // In lockstep the maps are exchanged at the feeder's ticks (messages.h ExchangeTick),
  // reliably, and sightings ride on them; in real time maps and sightings go out as the agent
  // goes, on topics of their own.
  AgentReaders(const transport::Participant& p, RobotId self, double lease_s, bool lockstep,
               const transport::OversizeCounter& oversize, std::size_t max_sample_bytes);
  // Wakes the wait set when any reader holds data.
  void Attach(transport::WaitSet& waitset) const;
  // Everything the readers hold, into the node; then the waiting ticks it can carry out. A tick
  // that waits longer than 5 wall seconds is logged with the messages it lacks.
  void Pump(AgentNode& node);
  ShellCounts Counts() const;

 private:
  bool SpeaksFor(transport::WriterPartitions& writers, dds_instance_handle_t publication, RobotId robot,
                 std::map<RobotId, std::uint64_t>& refused);
  bool FromFeeder(transport::FeederSource& source, transport::WriterPartitions& writers,
                  dds_instance_handle_t publication, const char* what);
  void LogWaitingTick(const AgentNode& node);

  transport::Reader<Odometry> odom_;
  transport::Reader<Scan> scans_;
  transport::Reader<RadioLinks> links_;
  transport::Reader<MapMessage> maps_;
  std::optional<transport::Reader<Sighting>> sightings_;
  transport::Reader<ExchangeTick> ticks_;
  transport::WriterPartitions map_writers_, links_writers_, tick_writers_;
  std::optional<transport::WriterPartitions> sighting_writers_;
  const transport::OversizeCounter& oversize_;
  std::size_t max_sample_bytes_;
  ShellCounts counts_;  // the refusals and lost peers; the transport's drops are read at Counts
  transport::FeederSource links_source_, ticks_source_;
  bool warned_ = false, feeder_warned_ = false;
  // Exchange ticks not carried out yet (they wait for their link table or a peer's message),
  // in the order they came.
  std::deque<ExchangeTick> pending_ticks_;
  std::optional<std::chrono::steady_clock::time_point> tick_waiting_since_;
};

}  // namespace mapmesh
