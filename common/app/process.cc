#include "common/app/process.h"

#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <cstdio>

#include "common/config/config_error.h"
#include "common/io/run_files.h"

namespace mapmesh::app {

void AddScenarioOptions(CLI::App& app, ProcessOptions& o) {
  app.add_option("--scenario", o.scenario_path, "scenario YAML file (see docs/SCENARIOS.md)")->required();
  app.add_option("--agents", o.agents, "number of robots in the run (default: the scenario's)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--set", o.sets, "override a scenario key: key.path=value (repeatable)");
}

void AddDdsOptions(CLI::App& app, ProcessOptions& o, bool domain_required) {
  auto* d = app.add_option("--domain", o.domain, "DDS domain id (scripts/swarm leases a free one)")
                ->check(CLI::Range(0, 232));
  if (domain_required) d->required();
  app.add_option("--dds-config", o.dds_config,
                 "Cyclone DDS XML config (default: CYCLONEDDS_URI, else config/cyclonedds-loopback.xml)");
  app.add_option("--log-level", o.log_level, "trace|debug|info|warn|error")
      ->check(CLI::IsMember({"trace", "debug", "info", "warn", "error"}));
}

std::optional<int> ParseArgs(CLI::App& app, const char* prog, int argc, char** argv) {
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    if (e.get_exit_code() == 0) return app.exit(e);
    std::fprintf(stderr, "%s: %s (see --help)\n", prog, e.what());
    return 2;
  }
  return std::nullopt;
}

void SetupLogging(const std::string& tag, const std::string& level) {
  auto logger = spdlog::stderr_color_mt(tag);
  spdlog::set_default_logger(logger);
  spdlog::set_pattern("[%H:%M:%S.%e] [" + tag + "] [%l] %v");
  spdlog::set_level(spdlog::level::from_str(level));
}

std::optional<Scenario> LoadScenarioOrReport(const char* prog, const ProcessOptions& o) {
  std::vector<ConfigOverride> overrides;
  try {
    for (const auto& s : o.sets) overrides.push_back(ParseOverride(s));
  } catch (const ConfigError& e) {  // "--set key: reason", reported like the overrides' other errors
    std::fprintf(stderr, "%s: %s: %s\n", prog, o.scenario_path.c_str(), e.what());
    return std::nullopt;
  }
  try {
    return LoadScenario(o.scenario_path, overrides, o.agents);
  } catch (const ConfigError& e) {
    std::fprintf(stderr, "%s: %s\n", prog, e.what());
    return std::nullopt;
  }
}

std::string DefaultDdsConfig() { return MAPMESH_SOURCE_DIR "/config/cyclonedds-loopback.xml"; }
std::string DefaultDatasetsRoot() { return MAPMESH_SOURCE_DIR "/../shared/datasets"; }

int GuardedMain(const char* prog, const std::function<int()>& fn) {
  try {
    return fn();
  } catch (const io::WriteError& e) {
    std::fprintf(stderr, "%s: %s\n", prog, e.what());
    return kExitWriteFailed;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s: %s\n", prog, e.what());
    return 1;
  }
}

}  // namespace mapmesh::app
