#include "common/transport/submap_signer.h"

#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <string>

namespace mapmesh::transport {
namespace {

// A run's identities made with the openssl tool as the launcher makes them: a CA, agents 1
// and 2 signed by it; agent 3's certificate by another CA; agent4.pem holding the CA's
// certificate of agent 5. No agent 6.
class SubmapSignerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    if (std::system("openssl version > /dev/null 2>&1") != 0) GTEST_SKIP() << "no openssl tool";
    dir_ = std::filesystem::temp_directory_path() / ("mapmesh_signer_" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir_);
    const std::string ec = " -newkey ec -pkeyopt ec_paramgen_curve:prime256v1 -nodes";
    const auto run = [](const std::string& cmd) {
      ASSERT_EQ(std::system((cmd + " > /dev/null 2>&1").c_str()), 0) << cmd;
    };
    for (const char* ca : {"ca", "rogue"}) {
      run("openssl req -x509" + ec + " -keyout " + Path(ca) + ".key -out " + Path(ca) + ".pem -subj /CN=" + ca +
          " -days 1");
    }
    const auto identity = [&](const std::string& file, const std::string& cn, const std::string& ca) {
      run("openssl req -new" + ec + " -keyout " + Path(file) + ".key -out " + Path(file) +
          ".csr -subj /O=mapmesh/CN=" + cn);
      run("openssl x509 -req -in " + Path(file) + ".csr -CA " + Path(ca) + ".pem -CAkey " + Path(ca) +
          ".key -CAcreateserial -out " + Path(file) + ".pem -days 1");
      ::chmod((Path(file) + ".key").c_str(), 0600);
    };
    identity("agent1", "agent1", "ca");
    identity("agent2", "agent2", "ca");
    identity("agent3", "agent3", "rogue");
    identity("agent4", "agent5", "ca");
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::string Path(const std::string& name) const { return (dir_ / name).string(); }
  SecurityFiles Files(const std::string& who) const { return {Path(who) + ".pem", Path(who) + ".key", Path("ca.pem")}; }
  std::filesystem::path dir_;
};

const std::vector<std::uint8_t> kBytes = {0x4d, 0x53, 1, 0, 2, 0, 0, 0, 7, 7, 7};

TEST_F(SubmapSignerTest, ARobotsSignatureVerifiesAsItsOnlyOverItsBytes) {
  std::string why;
  std::unique_ptr<SubmapSigner> one = SubmapSigner::Make(Files("agent1"), 1, "", &why);
  ASSERT_NE(one, nullptr) << why;
  std::unique_ptr<SubmapSigner> two = SubmapSigner::Make(Files("agent2"), 2, "", &why);
  ASSERT_NE(two, nullptr) << why;
  const std::vector<std::uint8_t> sig = one->Sign(kBytes);
  ASSERT_FALSE(sig.empty());
  EXPECT_EQ(sig.size(), 64u);  // P-256 ECDSA as r | s: the same length every time
  for (int k = 0; k < 20; ++k) EXPECT_EQ(one->Sign(kBytes).size(), 64u);
  EXPECT_EQ(two->Verify(1, kBytes, sig), SubmapOrigin::Verdict::kValid);
  EXPECT_EQ(one->Verify(1, kBytes, sig), SubmapOrigin::Verdict::kValid);                 // its own, after a restart
  EXPECT_EQ(two->Verify(1, kBytes, two->Sign(kBytes)), SubmapOrigin::Verdict::kForged);  // 2 claiming 1's
  std::vector<std::uint8_t> edited = kBytes;
  edited.back() ^= 1;
  EXPECT_EQ(two->Verify(1, edited, sig), SubmapOrigin::Verdict::kForged);
  std::vector<std::uint8_t> bent = sig;
  bent[sig.size() / 2] ^= 0x40;
  EXPECT_EQ(two->Verify(1, kBytes, bent), SubmapOrigin::Verdict::kForged);
  EXPECT_EQ(two->Verify(1, kBytes, {}), SubmapOrigin::Verdict::kUnsigned);
  EXPECT_EQ(two->Verify(1, kBytes, std::vector<std::uint8_t>(kMaxSubmapSignatureBytes + 1, 1)),
            SubmapOrigin::Verdict::kUnsigned);
  EXPECT_EQ(two->PeerProblem(1), std::nullopt);
}

// Robots whose certificate is missing, not the run CA's, or another robot's are unknown
// signers: nothing they sign is taken, and the log line says why.
TEST_F(SubmapSignerTest, ACertificateMissingOrNotTheRunCasOfThatRobotMakesAnUnknownSigner) {
  std::string why;
  std::unique_ptr<SubmapSigner> one = SubmapSigner::Make(Files("agent1"), 1, "", &why);
  ASSERT_NE(one, nullptr) << why;
  std::unique_ptr<SubmapSigner> rogue = SubmapSigner::Make(Files("agent3"), std::nullopt, "", &why);
  ASSERT_NE(rogue, nullptr) << why;
  EXPECT_EQ(one->Verify(3, kBytes, rogue->Sign(kBytes)), SubmapOrigin::Verdict::kUnknownSigner);
  EXPECT_EQ(one->PeerProblem(3), Path("agent3.pem") + ": not the identity CA's certificate of agent3");
  EXPECT_EQ(one->PeerProblem(4), Path("agent4.pem") + ": not the identity CA's certificate of agent4");
  EXPECT_EQ(one->PeerProblem(6), Path("agent6.pem") + ": cannot read a PEM certificate");
  EXPECT_EQ(one->Verify(6, kBytes, one->Sign(kBytes)), SubmapOrigin::Verdict::kUnknownSigner);
  // Another directory of peers' certificates.
  std::unique_ptr<SubmapSigner> elsewhere = SubmapSigner::Make(Files("agent1"), 1, Path("none"), &why);
  ASSERT_NE(elsewhere, nullptr) << why;
  EXPECT_EQ(elsewhere->CertificatePath(2), Path("none") + "/agent2.pem");
  EXPECT_EQ(elsewhere->Verify(2, kBytes, one->Sign(kBytes)), SubmapOrigin::Verdict::kUnknownSigner);
}

TEST_F(SubmapSignerTest, AnAgentsOwnIdentityMustBeTheRunCasCertificateOfItsRobot) {
  std::string why;
  EXPECT_EQ(SubmapSigner::Make(Files("agent1"), 2, "", &why), nullptr);
  EXPECT_EQ(why, Path("agent1.pem") + ": not the identity CA's certificate of agent2 (common name agent1)");
  EXPECT_EQ(SubmapSigner::Make(Files("agent3"), 3, "", &why), nullptr);
  EXPECT_EQ(why, Path("agent3.pem") + ": not the identity CA's certificate of agent3 (common name agent3)");
  SecurityFiles mixed = Files("agent1");
  mixed.private_key = Path("agent2.key");
  EXPECT_EQ(SubmapSigner::Make(mixed, 1, "", &why), nullptr);
  EXPECT_EQ(why, Path("agent2.key") + ": the private key does not match the certificate " + Path("agent1.pem"));
  SecurityFiles no_ca = Files("agent1");
  no_ca.identity_ca.clear();
  EXPECT_EQ(SubmapSigner::Make(no_ca, 1, "", &why), nullptr);
  EXPECT_EQ(why, "the DDS config's <Security> names no IdentityCA file");
  no_ca.identity_ca = Path("missing.pem");
  EXPECT_EQ(SubmapSigner::Make(no_ca, 1, "", &why), nullptr);
  EXPECT_EQ(why, Path("missing.pem") + ": cannot read a PEM certificate (the identity CA)");
}

TEST(SecurityFilesOf, NamesTheIdentityCa) {
  const std::optional<SecurityFiles> f = SecurityFilesOf(
      "<Security><IdentityCA>file:/a/ca.pem</IdentityCA><IdentityCertificate>file:/a/agent2.pem"
      "</IdentityCertificate><PrivateKey>file:/a/agent2.key</PrivateKey></Security>");
  ASSERT_TRUE(f.has_value());
  EXPECT_EQ(f->identity_ca, "/a/ca.pem");
}

}  // namespace
}  // namespace mapmesh::transport
