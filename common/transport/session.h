#pragma once
// One process's DDS session: the domain (with mapmesh's loopback config unless told
// otherwise) and the participant every reader and writer hangs off.

#include <memory>
#include <string>

#include "common/transport/dds.h"

namespace mapmesh::transport {

class Session {
 public:
  // config_path: a Cyclone XML file. Empty: CYCLONEDDS_URI when set, else default_config. A
  // config with DDS Security has its identity files checked first (security_files.h); what is
  // wrong is thrown as std::runtime_error, one line naming the files.
  Session(int domain_id, const std::string& config_path, const std::string& default_config);
  const Participant& participant() const { return participant_; }
  // The configuration actually used ("CYCLONEDDS_URI" when taken from the environment).
  const std::string& config_used() const { return config_used_; }

 private:
  std::string config_used_;  // first: the domain's initialiser writes it
  std::unique_ptr<Domain> domain_;
  Participant participant_;
};

}  // namespace mapmesh::transport
