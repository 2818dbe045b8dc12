#include "common/transport/security_files.h"

#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <string>

namespace mapmesh::transport {
namespace {

TEST(SecurityFiles, AreTheCertificateAndKeyTheSecuritySectionNames) {
  EXPECT_FALSE(SecurityFilesOf("<CycloneDDS><Domain/></CycloneDDS>").has_value());
  const std::string
      xml = "<CycloneDDS><Domain><Security><Authentication>"
            "<IdentityCertificate> file:/a/agent2.pem </IdentityCertificate>"
            "<PrivateKey>file:///a/agent2.key</PrivateKey></Authentication></Security></Domain></CycloneDDS>";
  const std::optional<SecurityFiles> f = SecurityFilesOf(xml);
  ASSERT_TRUE(f.has_value());
  EXPECT_EQ(f->certificate, "/a/agent2.pem");
  EXPECT_EQ(f->private_key, "/a/agent2.key");
  // Inline data is Cyclone's to judge.
  EXPECT_FALSE(SecurityFilesOf("<Security><IdentityCertificate>data:,xyz</IdentityCertificate>"
                               "<PrivateKey>file:/k</PrivateKey></Security>")
                   .has_value());
}

// Two EC identities made with the openssl tool: each key matches only its own certificate, and
// only while others cannot read it.
class SecurityFilesCheck : public ::testing::Test {
 protected:
  void SetUp() override {
    if (std::system("openssl version > /dev/null 2>&1") != 0) GTEST_SKIP() << "no openssl tool";
    dir_ = std::filesystem::temp_directory_path() / ("mapmesh_sec_" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir_);
    for (const char* name : {"a", "b"}) {
      const std::string base = (dir_ / name).string();
      const std::string cmd = "openssl req -x509 -newkey ec -pkeyopt ec_paramgen_curve:prime256v1 -nodes -keyout " +
                              base + ".key -out " + base + ".pem -subj /CN=" + name + " -days 1 > /dev/null 2>&1";
      ASSERT_EQ(std::system(cmd.c_str()), 0);
      ::chmod((base + ".key").c_str(), 0600);
    }
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::string Path(const char* name) const { return (dir_ / name).string(); }
  std::filesystem::path dir_;
};

TEST_F(SecurityFilesCheck, AKeyMustBeItsCertificatesAndPrivate) {
  EXPECT_EQ(CheckSecurityFiles({Path("a.pem"), Path("a.key"), ""}), std::nullopt);
  EXPECT_EQ(CheckSecurityFiles({Path("a.pem"), Path("b.key"), ""}),
            Path("b.key") + ": the private key does not match the certificate " + Path("a.pem"));
  ::chmod(Path("a.key").c_str(), 0644);
  EXPECT_EQ(CheckSecurityFiles({Path("a.pem"), Path("a.key"), ""}),
            Path("a.key") + ": the private key is readable by others (mode 0644); chmod 600 it");
  ::chmod(Path("a.key").c_str(), 0400);  // stricter is fine
  EXPECT_EQ(CheckSecurityFiles({Path("a.pem"), Path("a.key"), ""}), std::nullopt);
  EXPECT_EQ(CheckSecurityFiles({Path("a.key"), Path("a.key"), ""}), Path("a.key") + ": not a PEM certificate");
  EXPECT_EQ(CheckSecurityFiles({Path("a.pem"), Path("missing.key"), ""}),
            Path("missing.key") + ": cannot read the private key");
}

}  // namespace
}  // namespace mapmesh::transport
