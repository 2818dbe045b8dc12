#pragma once
// Readers of the scenario file's sections (world, source, robots' motion, sensor and path,
// radio, agent, feeder): each reads its keys strictly and checks their ranges. Used by
// scenario.cc only; docs/SCENARIOS.md lists every key.

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "common/config/scenario.h"
#include "common/config/yaml_reader.h"

namespace mapmesh::scenario_internal {

// world: control period, the landmark source (list, CSV file beside the scenario, or a
// generator) and the robots' bounds. dataset: landmarks are refused.
WorldOptions ReadWorld(YamlReader w, const std::string& scenario_dir, bool dataset);
// source: simulation or a dataset replay.
SourceOptions ReadSource(YamlReader r);
// A robot's motion, sensor and path, over the values already in o (defaults, then a robot).
void ReadMotion(YamlReader m, MotionOptions& o);
void ReadSensor(YamlReader s, SensorOptions& o);
// A lawnmower path without area_m covers world_bounds.
void ReadPath(YamlReader p, PathOptions& o, const Rect& world_bounds);
// Applies robots.defaults.preset (or a listed robot's preset) to motion and sensor.
void ReadPreset(YamlReader& r, RobotSpec& spec);
RadioOptions ReadRadio(YamlReader r);
AgentOptions ReadAgent(YamlReader a);
FeederOptions ReadFeeder(YamlReader f);
// The `faults:` section; duration_s > 0 bounds the times (0: not known yet, a whole dataset).
FaultOptions ReadFaults(YamlReader f, double duration_s);

// Fails at key unless every value is within +-limits::kMaxCoordinateM.
void CheckCoordinates(YamlReader& r, const std::string& key, const std::vector<double>& values);
// Why path cannot serve as an input file ("no such file", "it is a directory", "not a regular
// file", "larger than N MiB ..."), or nullopt when it is a regular file of at most max_bytes.
std::optional<std::string> RegularFileProblem(const std::string& path, std::size_t max_bytes);

}  // namespace mapmesh::scenario_internal
