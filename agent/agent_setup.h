#pragma once
// An agent's options and run from a scenario: the only place the agent's code reads a
// Scenario (so the agent library itself does not depend on the scenario format).

#include <memory>

#include "agent/agent_node.h"
#include "common/config/scenario.h"

namespace mapmesh {

// What robot `self` of the scenario needs besides sc.agent: the run's robots, seed and end,
// the radio's losses, and the robot's motion model, noise and sensor. The robot must be in
// the scenario (checked).
AgentRun AgentRunFor(const Scenario& sc, RobotId self);

// The local estimator the scenario asks for, for robot `self`.
std::unique_ptr<LocalMapper> MakeLocalMapper(const Scenario& sc, RobotId self);

}  // namespace mapmesh
