#include "common/transport/session.h"

#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>

#include "common/transport/security_files.h"

namespace mapmesh::transport {
namespace {

// Cyclone reads a list of files and XML fragments, later ones overriding earlier ones.
std::string WithMaxSampleSize(std::string config, std::size_t max_sample_bytes) {
  if (max_sample_bytes == 0) return config;
  return config + ",<CycloneDDS><Domain Id=\"any\"><Internal><MaxSampleSize>" + std::to_string(max_sample_bytes) +
         " B</MaxSampleSize></Internal></Domain></CycloneDDS>";
}

std::unique_ptr<Domain> MakeDomain(int domain_id, const std::string& config_path, const std::string& default_config,
                                   std::size_t max_sample_bytes, std::string& used,
                                   std::optional<SecurityFiles>& security) {
  std::string path = config_path;
  if (path.empty()) {
    const char* env = std::getenv("CYCLONEDDS_URI");
    if (env && *env) {
      used = "CYCLONEDDS_URI";
      if (max_sample_bytes == 0) return nullptr;
      return std::make_unique<Domain>(static_cast<dds_domainid_t>(domain_id), WithMaxSampleSize(env, max_sample_bytes));
    }
    path = default_config;
  }
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path + ": cannot open Cyclone DDS config");
  std::stringstream xml;
  xml << in.rdbuf();
  // Checked before the domain exists: a bad identity would come up and fail every handshake.
  if (const std::optional<SecurityFiles> files = SecurityFilesOf(xml.str())) {
    if (const std::optional<std::string> problem = CheckSecurityFiles(*files)) throw std::runtime_error(*problem);
    security = files;
  }
  used = path;
  return std::make_unique<Domain>(static_cast<dds_domainid_t>(domain_id),
                                  WithMaxSampleSize(xml.str(), max_sample_bytes));
}

}  // namespace

Session::Session(int domain_id, const std::string& config_path, const std::string& default_config,
                 std::size_t max_sample_bytes)
    : domain_(MakeDomain(domain_id, config_path, default_config, max_sample_bytes, config_used_, security_)),
      participant_(static_cast<dds_domainid_t>(domain_id)) {}

}  // namespace mapmesh::transport
