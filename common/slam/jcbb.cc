#include "common/slam/jcbb.h"

#include <algorithm>
#include <limits>

#include "common/solver/chi2.h"

namespace mapmesh {
namespace {

class Search {
 public:
  Search(const std::vector<std::vector<int>>& candidates, const JointDistance& joint_d2, double p, long max_nodes)
      : candidates_(candidates), joint_d2_(joint_d2), p_(p), max_nodes_(max_nodes), option_(candidates.size(), -1) {
    result_.option = option_;
    result_.joint_d2 = std::numeric_limits<double>::infinity();
  }

  JcbbResult Run() {
    Visit(0);
    result_.nodes = nodes_;
    if (result_.pairings == 0) result_.joint_d2 = 0.0;
    return result_;
  }

 private:
  // Item k next, with the pairings made so far in current_.
  void Visit(std::size_t k) {
    if (++nodes_ > max_nodes_) {
      result_.node_limit = true;
      return;
    }
    const std::size_t n = candidates_.size();
    const int pairs = static_cast<int>(current_.size());
    if (pairs + static_cast<int>(n - k) < result_.pairings) return;  // cannot reach the best
    if (k == n) {
      const double d2 = pairs == 0 ? 0.0 : d2_.back();
      if (pairs > result_.pairings || (pairs == result_.pairings && d2 < result_.joint_d2)) {
        result_.pairings = pairs;
        result_.joint_d2 = d2;
        result_.option = option_;
      }
      return;
    }
    const std::vector<int>& options = candidates_[k];
    for (std::size_t o = 0; o < options.size(); ++o) {
      const int target = options[o];
      if (std::any_of(current_.begin(), current_.end(), [&](const JcbbPairing& q) { return q.target == target; })) {
        continue;  // each target at most once
      }
      current_.push_back({static_cast<int>(k), static_cast<int>(o), target});
      const double d2 = joint_d2_(current_);
      if (d2 < Threshold(pairs + 1)) {
        option_[k] = static_cast<int>(o);
        d2_.push_back(d2);
        Visit(k + 1);
        d2_.pop_back();
        option_[k] = -1;
      }
      current_.pop_back();
    }
    Visit(k + 1);  // item k unpaired
  }

  double Threshold(int pairs) {
    if (thresholds_.size() <= static_cast<std::size_t>(pairs)) thresholds_.resize(pairs + 1, -1.0);
    if (thresholds_[pairs] < 0) thresholds_[pairs] = Chi2Quantile(p_, 2 * pairs);
    return thresholds_[pairs];
  }

  const std::vector<std::vector<int>>& candidates_;
  const JointDistance& joint_d2_;
  double p_;
  long max_nodes_;
  long nodes_ = 0;
  std::vector<JcbbPairing> current_;
  std::vector<double> d2_;  // joint distance of current_'s first 1, 2, ... pairings
  std::vector<int> option_;
  std::vector<double> thresholds_;
  JcbbResult result_;
};

}  // namespace

JcbbResult JointCompatibility(const std::vector<std::vector<int>>& candidates, const JointDistance& joint_d2,
                              double gate_probability, long max_nodes) {
  return Search(candidates, joint_d2, gate_probability, max_nodes).Run();
}

}  // namespace mapmesh
