#include "agent/agent_dds.h"

#include <spdlog/spdlog.h>

#include <string>

namespace mapmesh {
namespace {

namespace tp = transport;

double WallNow() { return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count(); }

// The tags the wait set reports (unused beyond waking it).
enum Tag : dds_attach_t { kOdom = 1, kScans = 2, kLinks = 3, kMaps = 4, kSightings = 6, kTicks = 7 };

}  // namespace

DdsOutput::DdsOutput(const tp::Participant& p, double lease_s, RobotId self, bool lockstep)
    : maps_(p, tp::kMapTopic, tp::MapQosFor(lockstep, lease_s).Partition(tp::RobotPartition(self))),
      status_(p, tp::kStatusTopic, tp::StatusQos(lease_s).Partition(tp::RobotPartition(self))) {
  // In lockstep sightings ride on the tick's local map: no sighting topic.
  if (!lockstep) sightings_.emplace(p, tp::kSightingTopic, tp::SightingQos().Partition(tp::RobotPartition(self)));
}

void DdsOutput::PublishStatus(const AgentStatus& status) {
  status_.Write(status);
  repeat_at_ = Clock::now() + kStatusRepeat;
}

AgentReaders::AgentReaders(const tp::Participant& p, RobotId self, double lease_s, bool lockstep,
                           const tp::OversizeCounter& oversize, std::size_t max_sample_bytes)
    : odom_(p, tp::OdomTopic(self), tp::SensorQos()),
      scans_(p, tp::ScanTopic(self), tp::SensorQos()),
      links_(p, tp::kLinksTopic, tp::FeederTopicReader(tp::LinksQos())),
      maps_(p, tp::kMapTopic,
            (lockstep ? tp::LockstepMapQos(lease_s) : tp::MapQos(lease_s)).Partition(tp::kEveryRobotPartition)),
      ticks_(p, tp::kTickTopic, tp::FeederTopicReader(tp::TickQos())),
      map_writers_(maps_.raw()),
      links_writers_(links_.raw()),
      tick_writers_(ticks_.raw()),
      oversize_(oversize),
      max_sample_bytes_(max_sample_bytes) {
  if (!lockstep) {
    sightings_.emplace(p, tp::kSightingTopic, tp::SightingQos().Partition(tp::kEveryRobotPartition));
    sighting_writers_.emplace(sightings_->raw());
  }
}

void AgentReaders::Attach(tp::WaitSet& waitset) const {
  waitset.AttachReader(odom_.raw(), kOdom);
  waitset.AttachReader(scans_.raw(), kScans);
  waitset.AttachReader(links_.raw(), kLinks);
  waitset.AttachReader(maps_.raw(), kMaps);
  if (sightings_) waitset.AttachReader(sightings_->raw(), kSightings);
  waitset.AttachReader(ticks_.raw(), kTicks);
}

ShellCounts AgentReaders::Counts() const {
  ShellCounts c = counts_;
  c.links_not_from_feeder = links_source_.refused();
  c.ticks_not_from_feeder = ticks_source_.refused();
  c.oversize_dropped = oversize_.received();
  c.max_sample_bytes = max_sample_bytes_;
  return c;
}

bool AgentReaders::SpeaksFor(tp::WriterPartitions& writers, dds_instance_handle_t publication, RobotId robot,
                             std::map<RobotId, std::uint64_t>& refused) {
  if (tp::SpeaksFor(writers.Of(publication), robot)) return true;
  ++refused[robot];
  if (!warned_) {
    spdlog::warn("refused a sample claiming robot {} from a writer outside partition {} (counted in stats.json "
                 "impersonations_refused)",
                 robot, tp::RobotPartition(robot));
    warned_ = true;
  }
  return false;
}

bool AgentReaders::FromFeeder(tp::FeederSource& source, tp::WriterPartitions& writers,
                              dds_instance_handle_t publication, const char* what) {
  const tp::FeederSource::Verdict v = source.Judge(writers.Of(publication), writers.GuidOf(publication));
  if (v == tp::FeederSource::Verdict::kFeeder) return true;
  if (!feeder_warned_) {
    spdlog::warn("refused {} from {} (counted in stats.json not_from_feeder)", what,
                 v == tp::FeederSource::Verdict::kSecondWriter ? "a second writer in the feeder's partition"
                                                               : "a writer outside the feeder's partition");
    feeder_warned_ = true;
  }
  return false;
}

void AgentReaders::Pump(AgentNode& node) {
  for (const auto& s : links_.Take()) {
    if (s.valid && FromFeeder(links_source_, links_writers_, s.publication, "a link table")) node.OnLinks(s.value);
  }
  for (const auto& s : scans_.Take()) {
    if (s.valid) node.OnScan(s.value);
  }
  for (const auto& s : odom_.Take()) {
    if (s.valid) node.OnOdometry(s.value);
  }
  if (sightings_) {
    for (const auto& s : sightings_->Take()) {
      if (s.valid && SpeaksFor(*sighting_writers_, s.publication, s.value.robot_id, counts_.sightings_impersonated))
        node.OnSighting(s.value);
    }
  }
  for (const auto& s : maps_.Take()) {
    if (s.valid && SpeaksFor(map_writers_, s.publication, s.value.robot_id, counts_.maps_impersonated)) {
      const std::string* guid = map_writers_.GuidOf(s.publication);  // known: SpeaksFor found the writer
      node.OnMap(s.value, guid ? *guid : std::string());
    }
    // A peer's writer is gone: an invalid sample carries that, or the state of its last
    // sample when that was still unread.
    if (!s.alive && node.OnPeerLiveliness(s.value.robot_id, false)) {
      if (!counts_.peers_lost_wall.count(s.value.robot_id)) {
        spdlog::info("peer {} lost (liveliness)", s.value.robot_id);
        counts_.peers_lost_wall[s.value.robot_id] = WallNow();
      }
    }
  }
  for (const auto& s : ticks_.Take()) {
    if (s.valid && FromFeeder(ticks_source_, tick_writers_, s.publication, "an exchange tick"))
      pending_ticks_.push_back(s.value);
  }
  while (!pending_ticks_.empty() && node.OnTick(pending_ticks_.front())) {
    pending_ticks_.pop_front();
    tick_waiting_since_.reset();
  }
  if (!pending_ticks_.empty()) LogWaitingTick(node);
}

// A tick that waits long: say what for (a message that never comes holds the whole run).
void AgentReaders::LogWaitingTick(const AgentNode& node) {
  const auto now = std::chrono::steady_clock::now();
  if (!tick_waiting_since_) tick_waiting_since_ = now;
  if (now - *tick_waiting_since_ <= std::chrono::seconds(5)) return;
  const ExchangeTick& t = pending_ticks_.front();
  std::string what;
  for (const TickPeer& m : node.Missing(t)) what += fmt::format(" {}.{} ({} here)", m.robot, m.incarnation, m.messages);
  spdlog::warn("exchange tick {} ({}) waits: messages missing from{}", t.index,
               t.phase == TickPhase::kExchange ? "exchange" : "deliver", what.empty() ? " none" : what);
  tick_waiting_since_ = now;
}

}  // namespace mapmesh
