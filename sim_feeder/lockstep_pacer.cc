#include "sim_feeder/lockstep_pacer.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

namespace mapmesh {
namespace {
constexpr double kStampEps = 1e-9;
}  // namespace

LockstepPacer::LockstepPacer(const std::vector<RobotId>& ids, Options options, ProcessProbe probe)
    : options_(std::move(options)),
      probe_(std::move(probe)),
      tracker_(ids),
      holds_(options_.holds),
      next_barrier_(options_.window_s),
      next_exchange_(options_.lockstep && options_.exchange_period_s > 0 ? options_.exchange_period_s
                                                                         : std::numeric_limits<double>::infinity()) {
  std::sort(holds_.begin(), holds_.end());
  for (RobotId id : ids) matches_at_restart_[id] = 0;
}

bool LockstepPacer::OnStatus(const AgentStatus& status) {
  const RobotId id = status.robot_id;
  const bool was_silent = tracker_.IsSilent(id);
  tracker_.OnStatus(status);
  if (tracker_.IsUp(id) || tracker_.IsSilent(id)) sent_.Processed(id, status.processed_until);
  return was_silent && !tracker_.IsSilent(id);
}

std::optional<bool> LockstepPacer::OnStatusGone(RobotId id) {
  if (!matches_at_restart_.count(id) || tracker_.IsDead(id) || tracker_.IsSilent(id)) return std::nullopt;
  // While its process exists the agent is only silent (paused, say): still waited for.
  const std::optional<int> pid = tracker_.process(id);
  const bool exists = pid && probe_(*pid) != ProcessState::kGone;
  tracker_.OnGone(id, exists);
  if (!exists) sent_.Forget(id);
  return exists;
}

std::vector<RobotId> LockstepPacer::ReapSilent() {
  std::vector<RobotId> gone;
  for (RobotId id : tracker_.Silent()) {
    const std::optional<int> pid = tracker_.process(id);
    if (pid && probe_(*pid) != ProcessState::kGone) continue;
    tracker_.OnProcessGone(id);
    sent_.Forget(id);
    gone.push_back(id);
  }
  return gone;
}

std::vector<SentLog::Message> LockstepPacer::OnMatches(RobotId id, std::uint32_t total) {
  auto base = matches_at_restart_.find(id);
  if (base == matches_at_restart_.end()) return {};
  tracker_.SetSubscribed(id, total > base->second);
  // Matched anew without a restart: the agent's participant lapsed (it was paused) and is
  // back. Whatever it had not processed may have been lost with the old match.
  std::uint32_t& last = last_matches_[id];
  const bool first = total > base->second && last <= base->second;
  const bool again = total > last && last > base->second && !tracker_.IsDead(id);
  last = total;
  if (first && replay_due_[id] && !tracker_.IsDead(id)) {
    replay_due_[id] = false;
    if (streams_.size(id) > 0) replays_[id] = Replay{};
  }
  if (!again) return {};
  std::vector<SentLog::Message> out = sent_.Unprocessed(id);
  resent_ += out.size();
  return out;
}

namespace {
double StampOf(const SentLog::Message& m) {
  return std::visit([](const auto& x) { return x.stamp; }, m);
}
}  // namespace

std::vector<SentLog::Message> LockstepPacer::ReplayDue(RobotId id) {
  auto it = replays_.find(id);
  if (it == replays_.end()) return {};
  if (tracker_.IsDead(id)) {
    replays_.erase(it);
    return {};
  }
  Replay& r = it->second;
  if (r.first_sent && !tracker_.Lagging({{id, r.wait_for}}).empty()) return {};  // the last piece is not done
  if (r.first_sent && !tracker_.IsUp(id) && !tracker_.IsSilent(id)) return {};
  const std::vector<SentLog::Message>& stream = streams_.Of(id);
  if (r.next >= stream.size()) {
    replays_.erase(it);  // done: the agent has processed its whole stream
    return {};
  }
  // A piece: up to replay_span_s after its first message, ending after an odometry message that
  // closed a lockstep window when there is one (the agent reports those at once).
  const double until = StampOf(stream[r.next]) + options_.replay_span_s;
  std::size_t end = r.next, end_at_sync = r.next;
  for (std::size_t i = r.next; i < stream.size() && StampOf(stream[i]) <= until; ++i) {
    end = i + 1;
    if (const auto* o = std::get_if<Odometry>(&stream[i]); o && o->sync) end_at_sync = i + 1;
  }
  if (end_at_sync > r.next) end = end_at_sync;
  if (end == r.next) end = r.next + 1;
  std::vector<SentLog::Message> piece(stream.begin() + static_cast<std::ptrdiff_t>(r.next),
                                      stream.begin() + static_cast<std::ptrdiff_t>(end));
  for (const SentLog::Message& m : piece) {
    if (const auto* o = std::get_if<Odometry>(&m)) r.wait_for = std::max(r.wait_for, o->stamp);
    // Kept again until processed, like anything published in lockstep.
    if (options_.lockstep) std::visit([&](const auto& x) { sent_.Record(x); }, m);
  }
  r.next = end;
  r.first_sent = true;
  replayed_ += piece.size();
  return piece;
}

void LockstepPacer::OnControl(const ControlCommand& c, std::uint32_t total_matches) {
  switch (c.kind) {
    case ControlCommand::Kind::kDead: GiveUp(c.id); break;
    case ControlCommand::Kind::kExpect:
      if (matches_at_restart_.count(c.id)) {
        matches_at_restart_[c.id] = total_matches;
        last_matches_[c.id] = total_matches;
      }
      tracker_.ExpectRestart(c.id);
      sent_.Forget(c.id);
      replay_due_[c.id] = options_.keep_streams;
      break;
    case ControlCommand::Kind::kPid: tracker_.SetProcess(c.id, c.pid); break;
    case ControlCommand::Kind::kContinue: continue_ = true; break;
    case ControlCommand::Kind::kStop: break;
  }
}

void LockstepPacer::GiveUp(RobotId id) {
  tracker_.MarkDead(id);
  sent_.Forget(id);
}

std::optional<Odometry> LockstepPacer::Admit(const Odometry& o) {
  if (!options_.lockstep) return o;
  std::optional<Odometry> out;
  if (auto it = held_.find(o.robot_id); it != held_.end()) out = it->second;
  held_[o.robot_id] = o;
  return out;
}

bool LockstepPacer::IsBarrier(double stamp, bool last) const {
  return last || stamp + kStampEps >= next_barrier_ || stamp + kStampEps >= next_exchange_ ||
         (!holds_.empty() && stamp + kStampEps >= holds_.front());
}

std::vector<Odometry> LockstepPacer::CloseWindow(double stamp) {
  std::vector<Odometry> out;
  for (auto& [id, o] : held_) {
    o.sync = true;
    out.push_back(o);
  }
  held_.clear();
  while (next_barrier_ <= stamp + kStampEps) next_barrier_ += options_.window_s;
  return out;
}

void LockstepPacer::Published(const Odometry& o) {
  published_until_[o.robot_id] = o.stamp;
  if (options_.lockstep) sent_.Record(o);
  if (options_.keep_streams) streams_.Record(o);
}

void LockstepPacer::Published(const Scan& s) {
  if (options_.lockstep) sent_.Record(s);
  if (options_.keep_streams) streams_.Record(s);
}

int LockstepPacer::TakeHolds(double stamp) {
  int n = 0;
  while (!holds_.empty() && stamp + kStampEps >= holds_.front()) {
    holds_.erase(holds_.begin());
    ++n;
  }
  return n;
}

void LockstepPacer::BeginStartup(double wall_now, double timeout_s) { startup_deadline_ = wall_now + timeout_s; }

std::optional<std::vector<RobotId>> LockstepPacer::PollStartup(double wall_now) const {
  std::vector<RobotId> pending = tracker_.Pending();
  for (const auto& [id, r] : replays_) {
    if (std::find(pending.begin(), pending.end(), id) == pending.end()) pending.push_back(id);
  }
  if (pending.empty() || wall_now >= startup_deadline_) return pending;
  return std::nullopt;
}

void LockstepPacer::BeginBarrier(double wall_now) {
  barrier_best_ = -1.0;
  barrier_progress_at_ = wall_now;
}

LockstepPacer::BarrierPoll LockstepPacer::PollBarrier(double wall_now) {
  BarrierPoll poll;
  const std::vector<RobotId> lagging = tracker_.Lagging(published_until_);
  if (lagging.empty()) {
    poll.done = true;
    return poll;
  }
  poll.waiting = lagging;
  // Progress: the sum of what the lagging agents have processed grows. A stopped agent is
  // not stalled: it is waited for as long as it is stopped.
  double sum = 0.0;
  for (const AgentStatus& s : tracker_.Statuses()) {
    if (std::find(lagging.begin(), lagging.end(), s.robot_id) != lagging.end()) sum += s.processed_until;
  }
  const bool stopped = std::any_of(lagging.begin(), lagging.end(), [&](RobotId id) {
    const std::optional<int> pid = tracker_.process(id);
    return pid && probe_(*pid) == ProcessState::kStopped;
  });
  if (sum > barrier_best_ || stopped) {
    barrier_best_ = std::max(barrier_best_, sum);
    barrier_progress_at_ = wall_now;
  } else if (wall_now - barrier_progress_at_ > options_.stall_timeout_s) {
    for (RobotId id : lagging) GiveUp(id);
    poll.stalled = lagging;
    poll.done = true;
  }
  return poll;
}

std::optional<std::uint32_t> LockstepPacer::ExchangeDue(double stamp) {
  last_stamp_ = std::max(last_stamp_, stamp);
  if (stamp + kStampEps < next_exchange_) return std::nullopt;
  const double k = std::floor((stamp + kStampEps) / options_.exchange_period_s);
  next_exchange_ = (k + 1.0) * options_.exchange_period_s;
  last_exchange_ = static_cast<std::uint32_t>(k);
  return last_exchange_;
}

std::optional<LockstepPacer::Closing> LockstepPacer::ClosingExchange() const {
  if (!last_exchange_) return std::nullopt;
  return Closing{*last_exchange_ + 1, last_stamp_};
}

ExchangeTick LockstepPacer::BeginExchange(std::uint32_t index, double stamp, const RadioLinks& links, double wall_now) {
  tick_ = ExchangeTick{};
  tick_.index = index;
  tick_.stamp = stamp;
  tick_.phase = TickPhase::kExchange;
  tick_.links = links;
  for (const AgentStatus& s : tracker_.Statuses()) {
    if (tracker_.IsUp(s.robot_id) || tracker_.IsSilent(s.robot_id))
      tick_.peers.push_back({s.robot_id, s.incarnation, 0});
  }
  tick_begun_at_ = wall_now;
  return tick_;
}

std::vector<TickPeer> LockstepPacer::LiveListed() const {
  std::vector<TickPeer> out;
  for (const TickPeer& p : tick_.peers) {
    if (!tracker_.IsDead(p.robot)) out.push_back(p);
  }
  return out;
}

ExchangeTick LockstepPacer::BeginDeliver(double wall_now) {
  tick_.phase = TickPhase::kDeliver;
  tick_.links = RadioLinks{-1.0, {}};  // only the exchange phase's gates use it
  tick_.peers = LiveListed();
  for (TickPeer& p : tick_.peers) {
    for (const AgentStatus& s : tracker_.Statuses()) {
      if (s.robot_id == p.robot && s.incarnation == p.incarnation && s.tick_done == tick_.index)
        p.messages = s.tick_published;
    }
  }
  tick_begun_at_ = wall_now;
  return tick_;
}

LockstepPacer::TickPoll LockstepPacer::PollTick(double wall_now) {
  TickPoll poll;
  const std::vector<TickPeer> live = LiveListed();
  if (tick_.phase == TickPhase::kDeliver && live.size() < tick_.peers.size()) {
    poll.reissue = true;  // what a dead agent published may never arrive
    return poll;
  }
  std::vector<RobotId> lagging;
  for (const TickPeer& p : live) {
    bool answered = false;
    for (const AgentStatus& s : tracker_.Statuses()) {
      if (s.robot_id != p.robot || s.incarnation != p.incarnation) continue;
      answered = (tick_.phase == TickPhase::kExchange ? s.tick_done : s.tick_delivered) >= tick_.index;
    }
    if (!answered) lagging.push_back(p.robot);
  }
  if (lagging.empty()) {
    poll.done = true;
    return poll;
  }
  poll.waiting = lagging;
  // A stopped agent is waited for as long as it is stopped.
  const bool stopped = std::any_of(lagging.begin(), lagging.end(), [&](RobotId id) {
    const std::optional<int> pid = tracker_.process(id);
    return pid && probe_(*pid) == ProcessState::kStopped;
  });
  if (stopped) {
    tick_begun_at_ = wall_now;
  } else if (wall_now - tick_begun_at_ > options_.stall_timeout_s) {
    for (RobotId id : lagging) GiveUp(id);
    poll.stalled = lagging;
    poll.done = tick_.phase == TickPhase::kExchange;
    poll.reissue = !poll.done;
  }
  return poll;
}

}  // namespace mapmesh
