#pragma once
// Who hears whom, from the robots' true positions, once per link table (docs/SCENARIOS.md
// "radio"). Pure: the draws are functions of the scenario's seed, the pair and the table's stamp,
// so a lockstep run's tables are the same tables whatever the host's load.
//
// disc: two robots hear each other within range_m, unless a wall lies between them.
// log_distance: the log-distance path loss with log-normal shadowing (Rappaport, Wireless
// Communications, 2nd ed., section 4.9; ns-3's LogDistancePropagationLossModel) and the
// multi-wall loss (COST 231, Digital mobile radio towards future generation systems, 1999,
// its indoor multi-wall model). With the receiver's threshold at the mean received power at
// range_m, the margin of a link d apart through k walls is
//     m = -10 n log10(d / range_m) - k wall_loss_db                                    [dB]
// and the table's link is up when m + sigma X + w Z >= 0: X ~ N(0, 1) the link's shadowing, one
// draw per shadowing_period_s, and w Z (Z ~ N(0, 1), a draw per table) the packet error curve,
// whose success probability at a margin m is Phi(m / w). Over the shadowing, a table's link is
// up with probability Phi(m / sqrt(sigma^2 + w^2)) (UpProbability). With sigma = w = 0 and no
// walls it is the disc.

#include <cstdint>
#include <map>
#include <utility>
#include <vector>

#include "common/config/scenario.h"
#include "common/geometry/pose2.h"
#include "common/types/keyed_draw.h"  // NormalDraw: a function of its key alone
#include "common/types/messages.h"

namespace mapmesh {

struct RobotPosition {
  RobotId id = 0;
  double x = 0.0, y = 0.0;
};

// Every unordered pair (a < b) no further apart than range_m, sorted.
std::vector<Link> LinksInRange(const std::vector<RobotPosition>& robots, double range_m);

// The walls the segment p-q crosses (touching an end counts; a wall along the segment counts once).
int WallsCrossed(const std::vector<RadioWall>& walls, const Eigen::Vector2d& p, const Eigen::Vector2d& q);

// The spans in which each pair was linked, from the tables published in order: a pair's span
// runs from the first table holding it to one period after the last of an unbroken row.
class LinkSpans {
 public:
  struct Span {
    RobotId a = 0, b = 0;
    double start = 0.0, end = 0.0;
  };
  explicit LinkSpans(double period_s) : period_s_(period_s) {}
  void Add(const RadioLinks& table);
  const std::vector<Span>& spans() const { return spans_; }  // in order of their start
  std::uint64_t tables() const { return tables_; }

 private:
  double period_s_;
  std::vector<Span> spans_;
  std::map<std::pair<RobotId, RobotId>, std::size_t> open_;  // a pair of the last table -> its span
  std::uint64_t tables_ = 0;
};

class RadioModel {
 public:
  RadioModel(const RadioOptions& options, std::uint64_t seed) : options_(options), seed_(seed) {}

  // Every unordered pair (a < b) that hears each other in the table stamped `stamp`, sorted.
  std::vector<Link> Links(const std::vector<RobotPosition>& robots, double stamp) const;

  // log_distance: the margin (dB) of a link d apart through `walls` walls (+inf at d = 0).
  double Margin(double distance_m, int walls) const;
  // The probability that such a link is up in one table, over the shadowing and the packet
  // draw (disc: 1 within range and no wall between, else 0).
  double UpProbability(double distance_m, int walls) const;

 private:
  bool Up(RobotId a, RobotId b, double distance_m, int walls, double stamp) const;

  RadioOptions options_;
  std::uint64_t seed_;
};

}  // namespace mapmesh
