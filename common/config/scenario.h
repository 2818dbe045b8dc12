#pragma once
// Scenario file format v1: the one description of an experiment that the feeder, every
// agent and the launcher read. Every struct has defaults, so a minimal scenario is short;
// docs/SCENARIOS.md lists every key. Loading is strict (see yaml_reader.h).

#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "common/config/resolved.h"
#include "common/geometry/pose2.h"
#include "common/options/agent_options.h"
#include "common/slam/motion_model.h"
#include "common/types/choice.h"
#include "common/types/messages.h"

namespace mapmesh {

// An axis-aligned rectangle [xmin, ymin, xmax, ymax] in metres.
struct Rect {
  double xmin = 0.0, ymin = 0.0, xmax = 0.0, ymax = 0.0;
  double Width() const { return xmax - xmin; }
  double Height() const { return ymax - ymin; }
  bool Contains(const Eigen::Vector2d& p) const {
    return p.x() >= xmin && p.x() <= xmax && p.y() >= ymin && p.y() <= ymax;
  }
};

// Where the world's data comes from.
enum class SourceType { kSimulation, kMrclam, kVictoriaPark };
inline constexpr ChoiceTable<SourceType, 3> kSourceTypes{{{SourceType::kSimulation, "simulation"},
                                                          {SourceType::kMrclam, "mrclam"},
                                                          {SourceType::kVictoriaPark, "victoria_park"}}};

struct SourceOptions {
  SourceType type = SourceType::kSimulation;
  std::string dataset;            // folder under the datasets root (mrclam/MRCLAM_Dataset7, victoria_park)
  std::vector<RobotId> robots;    // mrclam: which of robots 1-5 (default all)
  double odometry_delay_s = 0.0;  // mrclam: commanded velocities take effect this much later
  int virtual_robots = 4;         // victoria_park: the run is split into this many robots
  double overlap_s = 60.0;        // victoria_park: time shared by consecutive segments
  bool IsDataset() const { return type != SourceType::kSimulation; }
};

// How landmarks are generated when the scenario does not list them: uniform (thesis 4.1.1),
// park (trees along paths) or disc (Downs).
enum class LandmarkLayout { kUniform, kPark, kDisc };
inline constexpr ChoiceTable<LandmarkLayout, 3> kLandmarkLayouts{
    {{LandmarkLayout::kUniform, "uniform"}, {LandmarkLayout::kPark, "park"}, {LandmarkLayout::kDisc, "disc"}}};

struct LandmarkGeneratorOptions {
  LandmarkLayout type = LandmarkLayout::kUniform;
  int count = 100;                 // number of landmarks
  Rect area_m{0, 0, 50, 50};       // uniform, park: where they are placed
  double min_spacing_m = 1.0;      // minimum distance between any two landmarks
  int paths = 4;                   // park: number of footpaths crossing the area
  double path_width_m = 4.0;       // park: trees stand at least half this from a path's centre line
  double scatter_fraction = 0.2;   // park: share of trees placed away from the paths
  Eigen::Vector2d center_m{0, 0};  // disc: centre
  double radius_m = 30.0;          // disc: radius (points at uniform radius and bearing, as Downs)
};

struct WorldOptions {
  double control_period_s = 0.1;  // simulation and odometry step
  // Exactly one landmark source for simulations: an inline list, a CSV file, or a generator.
  std::vector<Eigen::Vector2d> landmarks;             // from world.landmarks.list or .csv
  std::string landmarks_csv;                          // resolved path, empty if not used
  std::optional<LandmarkGeneratorOptions> generator;  // world.landmarks.generator
  Rect bounds_m;                                      // area robots may roam; defaults to the landmark area
};

inline constexpr ChoiceTable<MotionModel::Kind, 2> kMotionModels{
    {{MotionModel::Kind::kUnicycle, "unicycle"}, {MotionModel::Kind::kAckermann, "ackermann"}}};

// How a simulated robot steers to its next waypoint: thesis (Fig. 27: full turn rate or none)
// or smooth (proportional).
enum class Steering { kThesis, kSmooth };
inline constexpr ChoiceTable<Steering, 2> kSteerings{{{Steering::kThesis, "thesis"}, {Steering::kSmooth, "smooth"}}};

// Motion of a robot: its model, the simulated driving, and the noise on its odometry.
struct MotionOptions {
  MotionModel::Kind model = MotionModel::Kind::kUnicycle;  // unicycle | ackermann (Victoria Park's car)
  AckermannParams ackermann;                               // model ackermann: vehicle geometry
  Steering steering = Steering::kThesis;
  double speed_mps = 0.3;           // forward speed
  double max_turn_rate_dps = 30.0;  // turn-rate limit, deg/s
  double sigma_v_mps = 0.03;        // odometry noise on v
  double sigma_w_radps = 0.0524;    // odometry noise on w (3 deg/s)
  double sigma_steering_rad = 0.0;  // odometry noise on the steering angle (ackermann)
  double waypoint_radius_m = 1.0;   // switch to the next waypoint inside this radius
  int odometry_every_steps = 1;     // simulated odometry reports the mean control over this many steps
  static MotionOptions ThesisDefaults() { return {}; }
  static MotionOptions DownsDefaults();
};

// Range-bearing sensor of a robot.
struct SensorOptions {
  double max_range_m = 8.0;        // LMS-200-like range
  double fov_deg = 180.0;          // field of view, centred on the heading
  double sigma_range_m = 0.05;     // range noise
  double sigma_bearing_deg = 1.0;  // bearing noise
  int scan_every_steps = 5;        // one scan per this many control steps
  bool scan_at_start = false;      // simulation: also scan from the start pose, before the first control
                                   // step (anchors the map frame before any odometry noise)
  bool signatures = false;         // share landmark identities (known correspondence)
  bool sees_robots = true;         // simulation: scans also carry the other robots in view (kind robot,
                                   // signature = robot id), drawn from a generator of their own
  static SensorOptions ThesisDefaults() { return {}; }
  static SensorOptions DownsDefaults();
};

// A robot's path.
enum class PathType { kWaypoints, kRandom, kCircle, kLawnmower, kPark };
inline constexpr ChoiceTable<PathType, 5> kPathTypes{{{PathType::kWaypoints, "waypoints"},
                                                      {PathType::kRandom, "random"},
                                                      {PathType::kCircle, "circle"},
                                                      {PathType::kLawnmower, "lawnmower"},
                                                      {PathType::kPark, "park"}}};

struct PathOptions {
  PathType type = PathType::kRandom;
  std::vector<Eigen::Vector2d> points;  // waypoints (and the resolved waypoints of other types)
  int count = 8;                        // random: waypoints; circle: points around (default 36)
  std::optional<Rect> area_m;           // random, lawnmower: where (default: world bounds)
  Eigen::Vector2d center_m{0, 0};       // circle
  double radius_m = 10.0;               // circle
  double start_angle_deg = 0.0;         // circle: where on the circle the robot starts
  bool clockwise = false;               // circle
  double spacing_m = 8.0;               // lawnmower: distance between lanes
  int index = 0;                        // park: which footpath of the park generator
  bool loop = true;                     // start over after the last waypoint
};

struct RobotSpec {
  RobotId id = 0;
  Pose2 start;               // true start pose (theta in radians)
  bool start_given = false;  // false: drawn (or from the path or the dataset)
  PathOptions path;
  MotionOptions motion;
  SensorOptions sensor;
};

// How the feeder decides who hears whom (sim_feeder/radio_model.h; docs/SCENARIOS.md "radio").
enum class RadioModelKind { kDisc, kLogDistance };
inline constexpr ChoiceTable<RadioModelKind, 2> kRadioModels{
    {{RadioModelKind::kDisc, "disc"}, {RadioModelKind::kLogDistance, "log_distance"}}};

// A wall between two points: the radio's line of sight through it is blocked (disc) or loses
// wall_loss_db (log_distance).
struct RadioWall {
  Eigen::Vector2d a = Eigen::Vector2d::Zero();
  Eigen::Vector2d b = Eigen::Vector2d::Zero();
};

struct RadioOptions {
  RadioModelKind model = RadioModelKind::kDisc;
  // disc: robots further apart cannot hear each other; log_distance: the distance at which a link
  // in the open is up half the time (the mean received power there is the receiver's threshold);
  // 0: nobody hears anybody.
  double range_m = 20.0;
  // log_distance: received power falls by 10 n log10(d / range_m) dB (n the exponent), plus a
  // log-normal shadowing of sigma dB per link, drawn again every shadowing_period_s, plus
  // wall_loss_db per wall crossed; a table's link is up when the margin left, with the packet
  // error curve's own normal spread of packet_error_width_db, is positive.
  double path_loss_exponent = 3.0;
  double shadowing_sigma_db = 6.0;
  double shadowing_period_s = 10.0;
  double packet_error_width_db = 2.0;
  double wall_loss_db = 6.9;
  std::vector<RadioWall> walls;
  double loss_probability = 0.0;       // chance that a map message is dropped
  double bandwidth_bytes_per_s = 0.0;  // per link; 0 means unlimited
  // Each link's latency: latency_s plus a uniform draw in [0, latency_jitter_s) per pair (a
  // function of the seed and the pair); a message of B bytes arrives that long plus B /
  // bandwidth after it was sent (agent/radio_gate.h).
  double latency_s = 0.0;
  double latency_jitter_s = 0.0;
  double links_period_s = 0.5;  // how often the feeder publishes the link table
};

// How the feeder paces the run: lockstep (as fast as the agents go) or realtime.
enum class Pace { kLockstep, kRealtime };
inline constexpr ChoiceTable<Pace, 2> kPaces{{{Pace::kLockstep, "lockstep"}, {Pace::kRealtime, "realtime"}}};

struct FeederOptions {
  Pace pace = Pace::kLockstep;
  double realtime_factor = 1.0;     // realtime: scenario seconds per wall second
  double lockstep_window_s = 0.5;   // lockstep: data published between barriers (<= 10 s)
  double startup_timeout_s = 30.0;  // wall seconds to wait for every agent to appear
  double truth_period_s = 0.5;      // trajectory sampling in truth.json
  bool keep_streams = true;         // keep what each robot was sent, to replay it to a restarted agent
};

// A fault at scenario time (`faults:`), meaning what swarm run's --kill, --restart and --pause do.
struct FaultEvent {
  enum class Kind { kKill, kRestart, kPause };
  Kind kind = Kind::kKill;
  RobotId id = 0;
  double t = 0.0;        // scenario seconds
  double seconds = 0.0;  // a pause's length, wall seconds
};
// The experiment's fault schedule, saved with it; launched by swarm run beside its flags (which
// add to it), the whole schedule checked before anything starts.
struct FaultOptions {
  std::vector<FaultEvent> events;  // kills, then restarts, then pauses, each in file order
  std::string inject;              // inject.cases: mapmesh-inject's cases ("" none, "all", or a list)
  double inject_period_s = 0.2;    // inject.period_s
};

struct Scenario {
  int version = 1;
  std::string name;
  std::string description;
  std::string path;  // the file it was loaded from
  std::uint64_t seed = 1;
  double duration_s = 60.0;     // datasets: 0 until the feeder has read the data
  bool duration_given = false;  // datasets: false replays everything
  SourceOptions source;
  WorldOptions world;
  std::vector<RobotSpec> robots;  // resolved: exactly the robots of this run
  RadioOptions radio;
  AgentOptions agent;  // the agent section: each module's own options (common/options/agent_options.h)
  FeederOptions feeder;
  FaultOptions faults;
  // Every value key the loader read, as taken (given, overridden or its default): what the run
  // was made with (`mapmesh-feeder --check --events`, run.json, `swarm run --print-config`).
  ResolvedScenario resolved;

  // The robot with this id, or nullptr.
  const RobotSpec* FindRobot(RobotId id) const;
};

// A command-line override "a.b.c=value" (value parsed as YAML).
struct ConfigOverride {
  std::string key_path;
  std::string value;
};
// Parses "a.b.c=value"; throws ConfigError on a malformed string.
ConfigOverride ParseOverride(const std::string& text);

// Loads and validates a scenario. agents > 0 resizes the robot list to that many robots:
// the first listed ones, then robots generated from robots.defaults with seeded random
// starts and paths (mrclam: the first N robots; victoria_park: N virtual robots).
// Throws ConfigError (one line naming file, line and key) on any problem.
Scenario LoadScenario(const std::string& file, const std::vector<ConfigOverride>& overrides = {}, int agents = 0);

// Same, from YAML text (file is used only in messages and to resolve relative paths). With
// keys_read, collects the path of every key the loader asked for, present or not (list
// indices as []): what the docs test compares with docs/SCENARIOS.md.
Scenario ParseScenario(const std::string& yaml_text, const std::string& file,
                       const std::vector<ConfigOverride>& overrides = {}, int agents = 0,
                       std::set<std::string>* keys_read = nullptr);

// The motion model a robot's odometry is interpreted with.
MotionModel MotionModelFor(const MotionOptions& motion);

// Waypoints of a circle path and the pose at its start (on the circle, facing along it).
std::vector<Eigen::Vector2d> CircleWaypoints(const PathOptions& path, Pose2* start);
// Waypoints of a lawnmower (boustrophedon) path over area with lanes spacing_m apart.
std::vector<Eigen::Vector2d> LawnmowerWaypoints(const Rect& area, double spacing_m);

}  // namespace mapmesh
