#pragma once
// One process's DDS session: the domain (with mapmesh's loopback config unless told
// otherwise) and the participant every reader and writer hangs off.

#include <cstddef>
#include <memory>
#include <optional>
#include <string>

#include "common/transport/dds.h"
#include "common/transport/security_files.h"

namespace mapmesh::transport {

class Session {
 public:
  // config_path: a Cyclone XML file. Empty: CYCLONEDDS_URI when set, else default_config. A
  // config with DDS Security has its identity files checked first (security_files.h); what is
  // wrong is thrown as std::runtime_error, one line naming the files.
  // max_sample_bytes > 0: Cyclone's Internal/MaxSampleSize on top of the config, so that a sample
  // larger (serialised) is dropped unread by the transport, on either side, with Cyclone's
  // warning (issue R3: one 4 MB sample cost an agent 23 MB of its 16 MB before anything of ours
  // could refuse it).
  Session(int domain_id, const std::string& config_path, const std::string& default_config,
          std::size_t max_sample_bytes = 0);
  const Participant& participant() const { return participant_; }
  // The configuration actually used ("CYCLONEDDS_URI" when taken from the environment).
  const std::string& config_used() const { return config_used_; }
  // The identity files of the config's DDS Security section; nullopt for a plain config (or
  // one from CYCLONEDDS_URI, which is Cyclone's to read).
  const std::optional<SecurityFiles>& security() const { return security_; }

 private:
  std::string config_used_;  // first: the domain's initialiser writes them
  std::optional<SecurityFiles> security_;
  std::unique_ptr<Domain> domain_;
  Participant participant_;
};

}  // namespace mapmesh::transport
