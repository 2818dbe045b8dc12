#include "common/transport/session.h"

#include <cstdlib>
#include <fstream>
#include <sstream>

#include "common/transport/security_files.h"

namespace mapmesh::transport {
namespace {

std::unique_ptr<Domain> MakeDomain(int domain_id, const std::string& config_path, const std::string& default_config,
                                   std::string& used, std::optional<SecurityFiles>& security) {
  std::string path = config_path;
  if (path.empty()) {
    const char* env = std::getenv("CYCLONEDDS_URI");
    if (env && *env) {
      used = "CYCLONEDDS_URI";
      return nullptr;
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
  return std::make_unique<Domain>(static_cast<dds_domainid_t>(domain_id), xml.str());
}

}  // namespace

Session::Session(int domain_id, const std::string& config_path, const std::string& default_config)
    : domain_(MakeDomain(domain_id, config_path, default_config, config_used_, security_)),
      participant_(static_cast<dds_domainid_t>(domain_id)) {}

}  // namespace mapmesh::transport
