#pragma once
// What every mapmesh executable does the same way: its shared command-line options, argument
// errors as one line, logging to stderr, scenario loading with a one-line error, and a last
// catch around main. Shell-side (CLI11, spdlog, files); the pure core never includes it.

#include <CLI/CLI.hpp>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "common/config/scenario.h"

namespace mapmesh::app {

// Options shared by the feeder and the agents.
struct ProcessOptions {
  std::string scenario_path;
  std::vector<std::string> sets;  // --set key.path=value
  int agents = 0;                 // 0: the scenario's robot count
  int domain = -1;
  std::string dds_config;  // empty: CYCLONEDDS_URI, else the shipped loopback config
  std::string log_level = "info";
};

// --scenario, --agents, --set.
void AddScenarioOptions(CLI::App& app, ProcessOptions& o);
// --domain, --dds-config, --log-level.
void AddDdsOptions(CLI::App& app, ProcessOptions& o, bool domain_required);

// Parses argv. Returns the exit code to return at once (0 after --help, 2 with a one-line
// reason on bad arguments), or nullopt to go on.
std::optional<int> ParseArgs(CLI::App& app, const char* prog, int argc, char** argv);

// Logs to stderr as "[time] [tag] [level] message".
void SetupLogging(const std::string& tag, const std::string& level);

// Loads the scenario with the --set overrides; on a bad scenario prints "prog: reason" (one
// line naming file, line and key) and returns nullopt.
std::optional<Scenario> LoadScenarioOrReport(const char* prog, const ProcessOptions& o);

// The default Cyclone configuration shipped with the sources.
std::string DefaultDdsConfig();
// The default datasets root: ../shared/datasets beside the source checkout.
std::string DefaultDatasetsRoot();

// The exit code of a process that could not write a run file (io::WriteError: a full disk,
// an I/O error); the launcher reports it as such.
inline constexpr int kExitWriteFailed = 3;

// Runs fn; an exception that escapes it becomes "prog: what" on stderr and exit code 1
// (kExitWriteFailed for io::WriteError).
int GuardedMain(const char* prog, const std::function<int()>& fn);

}  // namespace mapmesh::app
