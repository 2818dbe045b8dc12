#include "common/transport/submap_signer.h"

#include <openssl/bn.h>
#include <openssl/ec.h>
#include <openssl/evp.h>
#include <openssl/pem.h>
#include <openssl/x509.h>
#include <openssl/x509_vfy.h>

#include <algorithm>
#include <cstdio>
#include <string_view>

namespace mapmesh::transport {
namespace {

constexpr std::string_view kContext = "mapmesh submap v1";

struct FileCloser {
  void operator()(std::FILE* f) const { std::fclose(f); }
};
using File = std::unique_ptr<std::FILE, FileCloser>;
using Cert = std::unique_ptr<X509, decltype(&X509_free)>;

Cert ReadCertificate(const std::string& path) {
  File f(std::fopen(path.c_str(), "r"));
  return Cert(f ? PEM_read_X509(f.get(), nullptr, nullptr, nullptr) : nullptr, X509_free);
}

std::string CommonName(X509* cert) {
  char cn[256] = {};
  const int n = X509_NAME_get_text_by_NID(X509_get_subject_name(cert), NID_commonName, cn, sizeof cn);
  return n > 0 ? std::string(cn, static_cast<std::size_t>(n)) : std::string();
}

// Whether the store's CA signed `cert` (dates not checked: see the header).
bool IssuedBy(X509_STORE* store, X509* cert) {
  std::unique_ptr<X509_STORE_CTX, decltype(&X509_STORE_CTX_free)> ctx(X509_STORE_CTX_new(), X509_STORE_CTX_free);
  if (!ctx || X509_STORE_CTX_init(ctx.get(), store, cert, nullptr) != 1) return false;
  X509_STORE_CTX_set_flags(ctx.get(), X509_V_FLAG_NO_CHECK_TIME);
  return X509_verify_cert(ctx.get()) == 1;
}

// What is signed: the context, then the submap's bytes.
std::vector<unsigned char> Message(std::span<const std::uint8_t> bytes) {
  std::vector<unsigned char> m(kContext.size() + bytes.size());
  std::copy(kContext.begin(), kContext.end(), m.begin());
  std::copy(bytes.begin(), bytes.end(), m.begin() + static_cast<std::ptrdiff_t>(kContext.size()));
  return m;
}

// SHA-256 for ECDSA and RSA keys; none for the keys that hash themselves (Ed25519, Ed448).
const EVP_MD* DigestFor(EVP_PKEY* key) {
  const int id = EVP_PKEY_get_base_id(key);
  return id == EVP_PKEY_ED25519 || id == EVP_PKEY_ED448 ? nullptr : EVP_sha256();
}

std::string RobotCertificateName(RobotId robot) { return "agent" + std::to_string(robot); }

// ECDSA signatures travel as r | s, each padded to the curve's size (64 bytes for P-256), not
// as DER (70 to 72 bytes): a signature's length must not vary from run to run, since bytes
// sent enter the radio gate's bandwidth (lockstep runs stay identical). Empty when `der` is
// not a signature of that size.
std::size_t EcHalf(EVP_PKEY* key) { return (static_cast<std::size_t>(EVP_PKEY_get_bits(key)) + 7) / 8; }

std::vector<std::uint8_t> DerToRaw(EVP_PKEY* key, std::span<const std::uint8_t> der) {
  const unsigned char* p = der.data();
  std::unique_ptr<ECDSA_SIG, decltype(&ECDSA_SIG_free)> sig(d2i_ECDSA_SIG(nullptr, &p, static_cast<long>(der.size())),
                                                            ECDSA_SIG_free);
  if (!sig) return {};
  const std::size_t half = EcHalf(key);
  std::vector<std::uint8_t> raw(2 * half);
  if (BN_bn2binpad(ECDSA_SIG_get0_r(sig.get()), raw.data(), static_cast<int>(half)) < 0 ||
      BN_bn2binpad(ECDSA_SIG_get0_s(sig.get()), raw.data() + half, static_cast<int>(half)) < 0) {
    return {};
  }
  return raw;
}

std::vector<std::uint8_t> RawToDer(EVP_PKEY* key, std::span<const std::uint8_t> raw) {
  const std::size_t half = EcHalf(key);
  if (raw.size() != 2 * half) return {};
  std::unique_ptr<ECDSA_SIG, decltype(&ECDSA_SIG_free)> sig(ECDSA_SIG_new(), ECDSA_SIG_free);
  BIGNUM* r = BN_bin2bn(raw.data(), static_cast<int>(half), nullptr);
  BIGNUM* s = BN_bin2bn(raw.data() + half, static_cast<int>(half), nullptr);
  if (!sig || r == nullptr || s == nullptr || ECDSA_SIG_set0(sig.get(), r, s) != 1) {
    BN_free(r);
    BN_free(s);
    return {};
  }
  unsigned char* out = nullptr;
  const int n = i2d_ECDSA_SIG(sig.get(), &out);
  if (n <= 0) return {};
  std::vector<std::uint8_t> der(out, out + n);
  OPENSSL_free(out);
  return der;
}

bool IsEc(EVP_PKEY* key) { return EVP_PKEY_get_base_id(key) == EVP_PKEY_EC; }

}  // namespace

void SubmapSigner::KeyFree::operator()(evp_pkey_st* k) const { EVP_PKEY_free(k); }
void SubmapSigner::StoreFree::operator()(x509_store_st* s) const { X509_STORE_free(s); }
SubmapSigner::~SubmapSigner() = default;

std::unique_ptr<SubmapSigner> SubmapSigner::Make(const SecurityFiles& files, std::optional<RobotId> self,
                                                 std::string peers_dir, std::string* error) {
  const auto fail = [error](std::string why) {
    if (error != nullptr) *error = std::move(why);
    return nullptr;
  };
  if (files.identity_ca.empty()) return fail("the DDS config's <Security> names no IdentityCA file");
  std::unique_ptr<SubmapSigner> s(new SubmapSigner());
  Cert ca = ReadCertificate(files.identity_ca);
  if (!ca) return fail(files.identity_ca + ": cannot read a PEM certificate (the identity CA)");
  s->ca_.reset(X509_STORE_new());
  if (!s->ca_ || X509_STORE_add_cert(s->ca_.get(), ca.get()) != 1)
    return fail(files.identity_ca + ": not usable as a CA");
  Cert own = ReadCertificate(files.certificate);
  if (!own) return fail(files.certificate + ": cannot read a PEM certificate");
  if (self && (CommonName(own.get()) != RobotCertificateName(*self) || !IssuedBy(s->ca_.get(), own.get()))) {
    return fail(files.certificate + ": not the identity CA's certificate of " + RobotCertificateName(*self) +
                " (common name " + CommonName(own.get()) + ")");
  }
  {
    File kf(std::fopen(files.private_key.c_str(), "r"));
    if (kf) s->key_.reset(PEM_read_PrivateKey(kf.get(), nullptr, nullptr, nullptr));
  }
  if (!s->key_) return fail(files.private_key + ": cannot read a PEM private key");
  if (X509_check_private_key(own.get(), s->key_.get()) != 1)
    return fail(files.private_key + ": the private key does not match the certificate " + files.certificate);
  if (peers_dir.empty()) {
    const auto slash = files.certificate.find_last_of('/');
    peers_dir = slash == std::string::npos ? "." : files.certificate.substr(0, slash);
  }
  s->peers_dir_ = std::move(peers_dir);
  return s;
}

std::string SubmapSigner::CertificatePath(RobotId robot) const {
  return peers_dir_ + "/" + RobotCertificateName(robot) + ".pem";
}

const SubmapSigner::Peer& SubmapSigner::PeerOf(RobotId robot) {
  auto it = peers_.find(robot);
  if (it == peers_.end()) {
    Peer p;
    const std::string path = CertificatePath(robot);
    if (Cert cert = ReadCertificate(path); !cert) {
      p.problem = path + ": cannot read a PEM certificate";
    } else if (CommonName(cert.get()) != RobotCertificateName(robot) || !IssuedBy(ca_.get(), cert.get())) {
      p.problem = path + ": not the identity CA's certificate of " + RobotCertificateName(robot);
    } else {
      p.key.reset(X509_get_pubkey(cert.get()));  // a reference of its own
      if (!p.key) p.problem = path + ": no usable public key";
    }
    it = peers_.emplace(robot, std::move(p)).first;
  }
  return it->second;
}

std::optional<std::string> SubmapSigner::PeerProblem(RobotId robot) {
  const Peer& p = PeerOf(robot);
  return p.key ? std::nullopt : std::optional<std::string>(p.problem);
}

std::vector<std::uint8_t> SubmapSigner::Sign(std::span<const std::uint8_t> bytes) {
  std::unique_ptr<EVP_MD_CTX, decltype(&EVP_MD_CTX_free)> ctx(EVP_MD_CTX_new(), EVP_MD_CTX_free);
  const std::vector<unsigned char> m = Message(bytes);
  std::size_t n = 0;
  if (!ctx || EVP_DigestSignInit(ctx.get(), nullptr, DigestFor(key_.get()), nullptr, key_.get()) != 1 ||
      EVP_DigestSign(ctx.get(), nullptr, &n, m.data(), m.size()) != 1) {
    return {};
  }
  std::vector<std::uint8_t> sig(n);
  if (EVP_DigestSign(ctx.get(), sig.data(), &n, m.data(), m.size()) != 1) return {};
  sig.resize(n);
  return IsEc(key_.get()) ? DerToRaw(key_.get(), sig) : sig;
}

SubmapOrigin::Verdict SubmapSigner::Verify(RobotId origin, std::span<const std::uint8_t> bytes,
                                           std::span<const std::uint8_t> signature) {
  if (signature.empty() || signature.size() > kMaxSubmapSignatureBytes) return Verdict::kUnsigned;
  EVP_PKEY* key = PeerOf(origin).key.get();
  if (key == nullptr) return Verdict::kUnknownSigner;
  std::vector<std::uint8_t> der;
  if (IsEc(key)) {
    der = RawToDer(key, signature);
    if (der.empty()) return Verdict::kForged;
    signature = der;
  }
  std::unique_ptr<EVP_MD_CTX, decltype(&EVP_MD_CTX_free)> ctx(EVP_MD_CTX_new(), EVP_MD_CTX_free);
  const std::vector<unsigned char> m = Message(bytes);
  const bool ok = ctx && EVP_DigestVerifyInit(ctx.get(), nullptr, DigestFor(key), nullptr, key) == 1 &&
                  EVP_DigestVerify(ctx.get(), signature.data(), signature.size(), m.data(), m.size()) == 1;
  return ok ? Verdict::kValid : Verdict::kForged;
}

}  // namespace mapmesh::transport
