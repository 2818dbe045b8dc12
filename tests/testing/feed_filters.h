#pragma once
// Feeds a simulated scenario's stream to landmark filters with known association: every
// odometry message to each filter's Predict, every scan's sightings of landmarks the first
// filter holds to each Update, and the rest to each Add.

#include <gtest/gtest.h>

#include <vector>

#include "common/config/scenario.h"
#include "common/slam/landmark_filter.h"
#include "sim_feeder/simulator.h"

namespace mapmesh::testing {

// inits, if given, counts the landmarks added.
inline void FeedFilters(const Scenario& sc, const std::vector<LandmarkFilter*>& filters, int* inits = nullptr) {
  Simulator sim(sc, BuildWorld(sc));
  while (!sim.Done()) {
    const FeedBatch b = sim.Next();
    for (const Odometry& o : b.odom) {
      for (LandmarkFilter* f : filters) f->Predict({o.v, o.w, 0.0}, o.dt);
    }
    for (const Scan& s : b.scans) {
      std::vector<std::pair<LandmarkId, Eigen::Vector2d>> known, fresh;
      for (const Observation& o : s.obs) {
        const auto id = static_cast<LandmarkId>(o.signature);
        (filters[0]->Has(id) ? known : fresh).push_back({id, {o.range, o.bearing}});
      }
      for (LandmarkFilter* f : filters) {
        ASSERT_TRUE(f->Update(known));
        for (const auto& [id, z] : fresh) f->Add(id, z);
      }
      if (inits) *inits += static_cast<int>(fresh.size());
    }
  }
}

}  // namespace mapmesh::testing
