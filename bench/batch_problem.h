#pragma once
// The batch problem the reference benchmarks share: park4 with 8 agents (200 s, scans every
// 0.5 s), every robot's log as `mapmesh-lab reference` reads it, and each robot's own batch
// optimum, from which the central solve starts.

#include <string>
#include <vector>

#include "common/config/scenario.h"
#include "common/slam/batch_slam.h"
#include "lab/reference.h"

namespace mapmesh::bench {

struct BatchProblemData {
  lab::ReferenceInput input;
  std::vector<BatchSolution> singles;
};

inline const BatchProblemData& Park4x8() {
  static const BatchProblemData data = [] {
    BatchProblemData d;
    Scenario sc = LoadScenario(MAPMESH_SOURCE_DIR "/scenarios/park4.yaml", {}, 8);
    d.input = lab::ReadReferenceInput(sc, "");
    for (const BatchRobotLog& log : d.input.logs) d.singles.push_back(SolveSingleRobotBatch(log));
    return d;
  }();
  return data;
}

}  // namespace mapmesh::bench
