#include "common/transport/security_files.h"

#include <openssl/evp.h>
#include <openssl/pem.h>
#include <openssl/x509.h>
#include <sys/stat.h>

#include <cstdio>
#include <memory>

namespace mapmesh::transport {
namespace {

// The text between <tag> and </tag>, trimmed; nullopt when absent.
std::optional<std::string> Element(const std::string& xml, const std::string& tag) {
  const std::string open = "<" + tag + ">", close = "</" + tag + ">";
  const auto a = xml.find(open);
  if (a == std::string::npos) return std::nullopt;
  const auto b = xml.find(close, a + open.size());
  if (b == std::string::npos) return std::nullopt;
  std::string v = xml.substr(a + open.size(), b - a - open.size());
  const auto first = v.find_first_not_of(" \t\r\n");
  if (first == std::string::npos) return std::string();
  return v.substr(first, v.find_last_not_of(" \t\r\n") - first + 1);
}

std::optional<std::string> FilePath(const std::optional<std::string>& uri) {
  if (!uri) return std::nullopt;
  if (uri->rfind("file://", 0) == 0) return uri->substr(7);
  if (uri->rfind("file:", 0) == 0) return uri->substr(5);
  return std::nullopt;
}

struct FileCloser {
  void operator()(std::FILE* f) const { std::fclose(f); }
};

}  // namespace

std::optional<SecurityFiles> SecurityFilesOf(const std::string& config_xml) {
  const auto security = config_xml.find("<Security>");
  if (security == std::string::npos) return std::nullopt;
  const std::string section = config_xml.substr(security);
  const std::optional<std::string> cert = FilePath(Element(section, "IdentityCertificate"));
  const std::optional<std::string> key = FilePath(Element(section, "PrivateKey"));
  if (!cert || !key) return std::nullopt;
  return SecurityFiles{*cert, *key, FilePath(Element(section, "IdentityCA")).value_or("")};
}

std::optional<std::string> CheckSecurityFiles(const SecurityFiles& files) {
  struct stat st {};
  if (::stat(files.private_key.c_str(), &st) != 0) return files.private_key + ": cannot read the private key";
  if ((st.st_mode & 077) != 0) {
    char mode[8];
    std::snprintf(mode, sizeof mode, "%04o", static_cast<unsigned>(st.st_mode & 07777));
    return files.private_key + ": the private key is readable by others (mode " + mode + "); chmod 600 it";
  }
  std::unique_ptr<std::FILE, FileCloser> cf(std::fopen(files.certificate.c_str(), "r"));
  if (!cf) return files.certificate + ": cannot read the certificate";
  std::unique_ptr<X509, decltype(&X509_free)> cert(PEM_read_X509(cf.get(), nullptr, nullptr, nullptr), X509_free);
  if (!cert) return files.certificate + ": not a PEM certificate";
  std::unique_ptr<std::FILE, FileCloser> kf(std::fopen(files.private_key.c_str(), "r"));
  if (!kf) return files.private_key + ": cannot read the private key";
  std::unique_ptr<EVP_PKEY, decltype(&EVP_PKEY_free)> key(PEM_read_PrivateKey(kf.get(), nullptr, nullptr, nullptr),
                                                          EVP_PKEY_free);
  if (!key) return files.private_key + ": not a PEM private key";
  if (X509_check_private_key(cert.get(), key.get()) != 1) {
    return files.private_key + ": the private key does not match the certificate " + files.certificate;
  }
  return std::nullopt;
}

}  // namespace mapmesh::transport
