#pragma once
// The bounds that scenario loading checks on every count, size, period, noise level and
// probability (docs/SCENARIOS.md lists each beside its key). Every allocation and loop that a
// scenario sizes is bounded by them, so a bad scenario fails at load with one line instead of
// hanging or exhausting memory. They are generous: every shipped scenario is far inside them.

#include <cstddef>

namespace mapmesh::limits {

// Counts.
inline constexpr int kMaxRobots = 1024;               // robots.count, --agents, robots.list, virtual_robots
inline constexpr int kMaxRobotId = 1000000;           // robots.list[].id
inline constexpr int kMaxLandmarks = 100000;          // generator count, landmarks.list, CSV rows
inline constexpr int kMaxWaypoints = 10000;           // path.points, path.count, lawnmower waypoints
inline constexpr int kMaxTotalWaypoints = 1000000;    // all robots' waypoints together (16 MB)
inline constexpr int kMaxParkPaths = 20;              // generator.paths
inline constexpr int kMaxScanEverySteps = 100000;     // sensor.scan_every_steps
inline constexpr int kMaxDropAfterFailures = 1000;    // agent.drop_after_failures
inline constexpr int kMaxJoinNetworkWindow = 100000;  // agent.join_network_window
inline constexpr int kMaxAlignmentsPerUpdate = 1000;  // agent.max_alignments_per_update, max_relay_checks_per_update
inline constexpr int kMaxRelayComparisonsPerUpdate = 1000000;  // agent.max_relay_comparisons_per_update
inline constexpr int kMaxSubmapSendBytes = 64 << 20;           // agent.submap_send_bytes
inline constexpr int kMaxSubmapsHeld = 1000000;                // agent.max_submaps_held
inline constexpr int kMinSubmapBytes = 4096;                   // agent.max_submap_bytes, max_chain_bytes, ...
inline constexpr int kMaxSubmapBytes = 2 << 20;                // ... (the codec's largest submap is 2.0 MB)
inline constexpr int kMaxSubmapBytesHeld = 128 << 20;          // agent.max_chain_bytes, max_submap_bytes_held:
                                                               // what a checkpoint can keep (io::CheckpointLimits)
inline constexpr std::size_t kMaxCsvBytes = 64u << 20;         // landmarks.csv file size
inline constexpr std::size_t kMaxScenarioBytes = 16u << 20;    // the scenario file itself
// Values (scalars, lists, mappings) in the scenario file, counted by a streaming pass before the
// document is built: yaml-cpp's document costs about 500 bytes a value, so this bounds a
// scenario's parse to about 60 MB whatever the file holds (15 MiB of "- 0" cost 2 GB and 8 s
// before; now 0.2 s and 60 MB to refuse). An inline landmarks.list holds ~33 000 [x, y] points
// within it; larger maps go in landmarks.csv.
inline constexpr std::size_t kMaxScenarioValues = 100000;

// Places and lengths (metres).
inline constexpr double kMaxCoordinateM = 1e5;  // |x|, |y| of every point, area, centre, start
inline constexpr double kMaxLengthM = 1e5;      // radii, spacings, widths, ranges, gates
inline constexpr double kMaxVehicleM = 100.0;   // ackermann geometry
inline constexpr double kMaxAngleDeg = 360.0;   // |start heading|, |circle start angle|

// Times (seconds).
inline constexpr double kMaxDurationS = 1e6;        // duration_s, overlap_s
inline constexpr int kMaxFaults = 10000;            // faults.kill, .restart, .pause: entries each
inline constexpr double kMaxPauseS = 86400.0;       // faults.pause[].seconds (swarm run --pause's bound)
inline constexpr double kMinControlPeriodS = 1e-3;  // world.control_period_s
inline constexpr double kMaxControlPeriodS = 10.0;
inline constexpr double kMaxSimulationSteps = 1e7;  // duration_s / control_period_s
inline constexpr double kMinPeriodS = 1e-3;         // every other period
inline constexpr double kMaxPeriodS = 1e6;
inline constexpr double kMinLeaseS = 0.1;               // agent.liveliness_lease_s: shorter leases would flood the host
inline constexpr double kMaxOdometryDelayS = 5.0;       // source.odometry_delay_s
inline constexpr double kMaxStartupTimeoutS = 86400.0;  // feeder.startup_timeout_s
inline constexpr double kMinLockstepWindowS = 0.01;     // feeder.lockstep_window_s
inline constexpr double kMaxLockstepWindowS = 10.0;

// Motion and noise.
inline constexpr double kMaxSpeedMps = 100.0;         // motion.speed_mps
inline constexpr double kMaxTurnRateDps = 3600.0;     // motion.max_turn_rate_dps
inline constexpr double kMaxSigmaVMps = 10.0;         // motion.sigma_v_mps
inline constexpr double kMaxSigmaWRadps = 10.0;       // motion.sigma_w_radps
inline constexpr double kMaxSigmaSteeringRad = 1.0;   // motion.sigma_steering_rad
inline constexpr double kMaxSigmaRangeM = 100.0;      // sensor.sigma_range_m
inline constexpr double kMaxSigmaBearingDeg = 180.0;  // sensor.sigma_bearing_deg

// Rates and thresholds.
inline constexpr double kMaxBandwidthBytesPerS = 1e12;  // radio.bandwidth_bytes_per_s
inline constexpr double kMaxLatencyS = 3600.0;          // radio.latency_s, latency_jitter_s
inline constexpr double kMaxPathLossExponent = 10.0;    // radio.path_loss_exponent
inline constexpr double kMaxDecibels = 200.0;           // radio.shadowing_sigma_db, wall_loss_db, ...
inline constexpr int kMaxRadioWalls = 10000;            // radio.walls
inline constexpr double kMinRealtimeFactor = 1e-3;      // feeder.realtime_factor
inline constexpr double kMaxRealtimeFactor = 1e4;
inline constexpr double kMaxChi2 = 1000.0;  // agent.new_landmark_chi2

}  // namespace mapmesh::limits
