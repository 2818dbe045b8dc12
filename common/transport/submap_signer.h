#pragma once
// The secure runs' SubmapOrigin (issue R3): the run's DDS Security identities vouch for the
// submaps. An agent signs each of its submaps with its identity's private key (SHA-256 with
// ECDSA or RSA, over the context "mapmesh submap v1" and the submap's bytes; an ECDSA signature
// as r | s of fixed size, 64 bytes for P-256, so that its length never varies); a receiver checks
// a robot's signature with that robot's certificate, read from `peers_dir/agent<robot>.pem`
// (the launcher's DIR/security holds every identity's certificate) and accepted only when the
// run's identity CA signed it and its common name is agent<robot>. Each certificate is read
// once, at the first submap that claims its robot; one missing or not the CA's makes every
// submap of that robot kUnknownSigner. Validity dates are not checked here (DDS Security
// checks them at each handshake; a verdict must not depend on the wall clock, so that lockstep
// runs stay identical).
//
// OpenSSL (libcrypto); reads files. Not thread-safe (one agent's thread).

#include <map>
#include <memory>
#include <optional>
#include <string>

#include "common/map/submap_origin.h"
#include "common/transport/security_files.h"

struct evp_pkey_st;
struct x509_store_st;

namespace mapmesh::transport {

class SubmapSigner final : public SubmapOrigin {
 public:
  // For robot `self`, from its identity files; `peers_dir` empty: the directory of its own
  // certificate. Fails (null, one line naming the file in *error) when the CA, the certificate
  // or the key cannot be read, the key is not the certificate's, or the certificate is not
  // the CA's agent<self>. Without `self` (tools: mapmesh-inject) it signs as whatever identity
  // the files are, the CA's or not.
  static std::unique_ptr<SubmapSigner> Make(const SecurityFiles& files, std::optional<RobotId> self,
                                            std::string peers_dir, std::string* error);
  ~SubmapSigner() override;

  std::vector<std::uint8_t> Sign(std::span<const std::uint8_t> bytes) override;
  Verdict Verify(RobotId origin, std::span<const std::uint8_t> bytes, std::span<const std::uint8_t> signature) override;

  // The certificate file robot `robot`'s signatures are checked with ...
  std::string CertificatePath(RobotId robot) const;
  // ... and what is wrong with it, one line naming it (nullopt: it is the CA's agent<robot>).
  std::optional<std::string> PeerProblem(RobotId robot);

 private:
  SubmapSigner() = default;
  struct KeyFree {
    void operator()(evp_pkey_st* k) const;
  };
  struct Peer {
    std::unique_ptr<evp_pkey_st, KeyFree> key;  // null: unknown signer, for the reason below
    std::string problem;
  };
  const Peer& PeerOf(RobotId robot);
  struct StoreFree {
    void operator()(x509_store_st* s) const;
  };
  std::unique_ptr<evp_pkey_st, KeyFree> key_;  // own private key
  std::unique_ptr<x509_store_st, StoreFree> ca_;
  std::string peers_dir_;
  std::map<RobotId, Peer> peers_;  // each read once
};

}  // namespace mapmesh::transport
