#include "common/io/checkpoint.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>

#include "common/io/base64.h"
#include "common/io/run_files.h"
#include "tests/testing/small_submap.h"

namespace mapmesh::io {
namespace {

constexpr RobotId kRobot = 3;
constexpr std::uint32_t kNow = 9;  // the resuming process's incarnation
constexpr const char* kName = "agent_3/checkpoint.json";

LandmarkMap SomeMap(int n, double offset) {
  LandmarkMap m;
  m.shape_sigma_m = 0.05;
  for (int i = 0; i < n; ++i) {
    Eigen::Matrix2d c;
    c << 0.1 + 0.01 * i, 0.02, 0.02, 0.3;
    m.landmarks.push_back({static_cast<std::uint32_t>(10 + i), i % 2 ? i : -1, {offset + 1.5 * i, -0.25 * i}, c});
  }
  return m;
}

IncarnationSnapshot Snapshot(std::uint32_t incarnation, int landmarks) {
  IncarnationSnapshot s;
  s.robot = kRobot;
  s.incarnation = incarnation;
  s.origin_stamp = 0.1 * incarnation;
  s.processed_until = 10.0 * incarnation + 0.3;
  s.local = SomeMap(landmarks, incarnation);
  s.global = SomeMap(landmarks + 2, -1.0 * incarnation);
  return s;
}

// A closed submap of two landmarks, as it travels (submap_codec.h).
std::vector<std::uint8_t> SubmapBytes(RobotId robot, std::uint32_t incarnation, std::uint32_t index, double x = 1.0) {
  return EncodeSubmap(mapmesh::testing::SmallSubmap(robot, incarnation, index, x));
}

AgentCheckpoint Checkpoint() {
  AgentCheckpoint c;
  static_cast<IncarnationSnapshot&>(c) = Snapshot(4, 3);
  c.earlier = {Snapshot(2, 2), Snapshot(1, 1)};
  c.submaps = {SubmapBytes(kRobot, 2, 0), SubmapBytes(kRobot, 4, 0), SubmapBytes(kRobot, 4, 1), SubmapBytes(5, 1, 0)};
  PeerAlignment a;
  a.robot = 5;
  a.incarnation = 2;
  a.origin_stamp = 0.25;
  a.frame_stamp = 0.4;
  a.to_own = {3.5, -1.25, 0.7};
  a.cov << 0.01, 0.001, 0.0, 0.001, 0.02, 0.0003, 0.0, 0.0003, 0.004;
  c.peers = {a};
  a.incarnation = 3;
  a.to_own = {-40.0, 12.0, -3.1};
  c.peers.push_back(a);
  return c;
}

void ExpectSameMap(const LandmarkMap& a, const LandmarkMap& b) {
  EXPECT_EQ(a.shape_sigma_m, b.shape_sigma_m);
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a.landmarks[i].id, b.landmarks[i].id);
    EXPECT_EQ(a.landmarks[i].signature, b.landmarks[i].signature);
    EXPECT_EQ(a.landmarks[i].mean, b.landmarks[i].mean);
    EXPECT_EQ(a.landmarks[i].cov, b.landmarks[i].cov);
  }
}

void ExpectSame(const IncarnationSnapshot& a, const IncarnationSnapshot& b) {
  EXPECT_EQ(a.robot, b.robot);
  EXPECT_EQ(a.incarnation, b.incarnation);
  EXPECT_EQ(a.origin_stamp, b.origin_stamp);
  EXPECT_EQ(a.processed_until, b.processed_until);
  ExpectSameMap(a.local, b.local);
  ExpectSameMap(a.global, b.global);
}

CheckpointLoad Parse(const std::string& text, const CheckpointLimits& limits = {}) {
  return ParseCheckpoint(text, kName, kRobot, kNow, limits);
}

// The reason a document is refused; fails the test if it is accepted or the reason is not
// one line naming the file.
std::string Refusal(const std::string& text, const CheckpointLimits& limits = {}) {
  const CheckpointLoad r = Parse(text, limits);
  EXPECT_FALSE(r.ok());
  EXPECT_FALSE(r.missing);
  EXPECT_EQ(r.error.rfind(std::string(kName) + ": ", 0), 0u) << r.error;
  EXPECT_EQ(r.error.find('\n'), std::string::npos) << r.error;
  return r.error;
}
std::string Refusal(const json& doc, const CheckpointLimits& limits = {}) { return Refusal(doc.dump(), limits); }

std::string Reason(const std::string& what) { return std::string(kName) + ": " + what; }

TEST(Checkpoint, RoundTripsWithEarlierIncarnations) {
  const AgentCheckpoint c = Checkpoint();
  const CheckpointLoad r = Parse(CheckpointToJson(c).dump(1));
  ASSERT_TRUE(r.ok()) << r.error;
  ExpectSame(*r.checkpoint, c);
  ASSERT_EQ(r.checkpoint->earlier.size(), 2u);
  ExpectSame(r.checkpoint->earlier[0], c.earlier[0]);
  ExpectSame(r.checkpoint->earlier[1], c.earlier[1]);
  EXPECT_EQ(r.checkpoint->submaps, c.submaps);  // byte for byte
  ASSERT_EQ(r.checkpoint->peers.size(), c.peers.size());
  for (std::size_t i = 0; i < c.peers.size(); ++i) {
    const PeerAlignment &got = r.checkpoint->peers[i], &want = c.peers[i];
    EXPECT_EQ(got.robot, want.robot);
    EXPECT_EQ(got.incarnation, want.incarnation);
    EXPECT_EQ(got.origin_stamp, want.origin_stamp);
    EXPECT_EQ(got.frame_stamp, want.frame_stamp);
    EXPECT_EQ(got.to_own.x, want.to_own.x);
    EXPECT_EQ(got.to_own.y, want.to_own.y);
    EXPECT_EQ(got.to_own.theta, want.to_own.theta);
    EXPECT_EQ(got.cov, want.cov);
  }
}

// The peers' frames the agent had placed (issue R3): each another robot's, once per incarnation,
// finite and within bounds, with a symmetric PSD covariance; files without them hold none.
TEST(Checkpoint, PeerAlignmentsAreValidatedAndNamed) {
  const json good = CheckpointToJson(Checkpoint());
  json none = good;
  none.erase("peers");
  const CheckpointLoad r = Parse(none.dump());
  ASSERT_TRUE(r.ok()) << r.error;
  EXPECT_TRUE(r.checkpoint->peers.empty());
  const auto with = [&](const std::function<void(json&)>& edit) {
    json doc = good;
    edit(doc["peers"][1]);
    return Refusal(doc);
  };
  EXPECT_EQ(with([](json& p) { p["robot"] = kRobot; }), Reason("peers[1] is of robot 3, the agent's own"));
  EXPECT_EQ(with([](json& p) { p["incarnation"] = 2; }), Reason("peers[1] repeats robot 5 incarnation 2 of peers[0]"));
  EXPECT_EQ(with([](json& p) { p["x"] = nullptr; }),
            Reason("peers[1].x is null, expected a finite number (NaN and inf are written as null)"));
  EXPECT_EQ(with([](json& p) { p["y"] = 2e5; }), Reason("peers[1].y is 200000 m, beyond the world bound of 100000 m"));
  EXPECT_EQ(with([](json& p) { p["theta"] = 7.0; }),
            Reason("peers[1].theta is 7 rad, expected an angle wrapped to [-pi, pi]"));
  EXPECT_EQ(with([](json& p) { p["frame_stamp"] = -1.0; }), Reason("peers[1].frame_stamp is -1, expected >= 0"));
  EXPECT_EQ(with([](json& p) { p.erase("origin_stamp"); }), Reason("peers[1].origin_stamp is missing"));
  EXPECT_EQ(with([](json& p) {
              p["cov"] = json::array({1, 2, 3});
            }),
            Reason("peers[1].cov is an array of 3, expected an array of 9 numbers (3 x 3, row by row)"));
  EXPECT_EQ(with([](json& p) { p["cov"][1] = 0.5; }), Reason("peers[1].cov is not symmetric positive semi-definite"));
  EXPECT_EQ(with([](json& p) {
              p["cov"] = json::array({1, 0, 0, 0, -1, 0, 0, 0, 1});
            }),
            Reason("peers[1].cov is not symmetric positive semi-definite"));
  EXPECT_EQ(with([](json& p) { p["robot"] = 1ull << 33; }),
            Reason("peers[1] names robot 8589934592 incarnation 3, beyond 32 bits"));
  json doc = good;
  doc["peers"] = json::object();
  EXPECT_EQ(Refusal(doc), Reason("peers is an object, expected an array"));
  CheckpointLimits one;
  one.max_peers = 1;
  EXPECT_EQ(Refusal(good, one), Reason("peers holds 2 alignments, more than the limit of 1"));
}

TEST(Checkpoint, NestedEarlierIsFlattenedInDocumentOrderAndWrittenFlat) {
  // An older writer's file: 4 { earlier: [2 { earlier: [1] }, 3] }.
  json one = CheckpointToJson(AgentCheckpoint{Snapshot(1, 1), {}, {}, {}});
  json two = CheckpointToJson(AgentCheckpoint{Snapshot(2, 2), {}, {}, {}});
  two["earlier"] = json::array({one});
  json three = CheckpointToJson(AgentCheckpoint{Snapshot(3, 0), {}, {}, {}});
  json four = CheckpointToJson(AgentCheckpoint{Snapshot(4, 3), {}, {}, {}});
  four["earlier"] = json::array({two, three});
  const CheckpointLoad r = Parse(four.dump());
  ASSERT_TRUE(r.ok()) << r.error;
  ASSERT_EQ(r.checkpoint->earlier.size(), 3u);
  EXPECT_EQ(r.checkpoint->earlier[0].incarnation, 2u);
  EXPECT_EQ(r.checkpoint->earlier[1].incarnation, 1u);
  EXPECT_EQ(r.checkpoint->earlier[2].incarnation, 3u);
  ExpectSame(r.checkpoint->earlier[1], Snapshot(1, 1));
  ExpectSame(r.checkpoint->earlier[2], Snapshot(3, 0));
  // Written back flat, and read back the same.
  const json flat = CheckpointToJson(*r.checkpoint);
  for (const json& e : flat.at("earlier")) EXPECT_FALSE(e.contains("earlier"));
  const CheckpointLoad again = Parse(flat.dump());
  ASSERT_TRUE(again.ok()) << again.error;
  ASSERT_EQ(again.checkpoint->earlier.size(), 3u);
  for (int i = 0; i < 3; ++i) ExpectSame(again.checkpoint->earlier[i], r.checkpoint->earlier[i]);
}

TEST(Checkpoint, EarlierAndOptionalKeysMayBeAbsent) {
  json doc = CheckpointToJson(Checkpoint());
  doc.erase("earlier");
  doc.erase("submaps");  // a file written before issue J1
  doc["local"].erase("shape_sigma_m");
  doc["local"]["landmarks"][0].erase("signature");
  doc["unknown_key_from_a_newer_writer"] = 1;
  const CheckpointLoad r = Parse(doc.dump());
  ASSERT_TRUE(r.ok()) << r.error;
  EXPECT_TRUE(r.checkpoint->earlier.empty());
  EXPECT_TRUE(r.checkpoint->submaps.empty());
  EXPECT_EQ(r.checkpoint->local.shape_sigma_m, 0.0);
  EXPECT_EQ(r.checkpoint->local.landmarks[0].signature, -1);
}

TEST(Checkpoint, WrongRobotAtTheTopAndInAnyEarlierEntry) {
  AgentCheckpoint c = Checkpoint();
  c.robot = 5;
  EXPECT_EQ(Refusal(CheckpointToJson(c)), Reason("robot is 5, expected 3"));
  c = Checkpoint();
  c.earlier.push_back(Snapshot(6, 1));
  c.earlier[2].robot = 5;
  EXPECT_EQ(Refusal(CheckpointToJson(c)), Reason("earlier[2].robot is 5, expected 3"));
  // Nested: the path names where it is in the file.
  json inner = CheckpointToJson(AgentCheckpoint{Snapshot(1, 1), {}, {}, {}});
  inner["robot"] = 4294967299ull;  // 3 + 2^32: must not wrap to 3
  json doc = CheckpointToJson(AgentCheckpoint{Snapshot(4, 1), {}, {}, {}});
  doc["earlier"] = json::array({CheckpointToJson(AgentCheckpoint{Snapshot(2, 1), {}, {}, {}})});
  doc["earlier"][0]["earlier"] = json::array({inner});
  EXPECT_EQ(Refusal(doc), Reason("earlier[0].earlier[0].robot is 4294967299, expected 3"));
}

TEST(Checkpoint, IncarnationsAreDistinctAndNotTheResumingOne) {
  AgentCheckpoint c = Checkpoint();
  c.incarnation = kNow;
  EXPECT_EQ(Refusal(CheckpointToJson(c)), Reason("incarnation 9 is the resuming process's own incarnation"));
  c = Checkpoint();
  c.earlier[1].incarnation = kNow;
  EXPECT_EQ(Refusal(CheckpointToJson(c)), Reason("earlier[1].incarnation 9 is the resuming process's own incarnation"));
  c = Checkpoint();
  c.earlier[1].incarnation = c.earlier[0].incarnation;
  EXPECT_EQ(Refusal(CheckpointToJson(c)), Reason("earlier[1].incarnation 2 repeats earlier[0].incarnation"));
  c = Checkpoint();
  c.earlier[0].incarnation = c.incarnation;
  EXPECT_EQ(Refusal(CheckpointToJson(c)), Reason("earlier[0].incarnation 4 repeats incarnation"));
  json doc = CheckpointToJson(Checkpoint());
  doc["incarnation"] = 4294967296ull;
  EXPECT_EQ(Refusal(doc), Reason("incarnation 4294967296 is beyond 32 bits"));
}

TEST(Checkpoint, StampsAreFiniteAndNotNegative) {
  AgentCheckpoint c = Checkpoint();
  c.origin_stamp = -0.5;
  EXPECT_EQ(Refusal(CheckpointToJson(c)), Reason("origin_stamp is -0.5, expected >= 0"));
  c = Checkpoint();
  c.earlier[0].processed_until = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(Refusal(CheckpointToJson(c)),
            Reason("earlier[0].processed_until is null, expected a finite number (NaN and inf are written as null)"));
}

// A resuming agent bounds stamps by its run's end: 1e300 s is refused, in any entry.
TEST(Checkpoint, StampsAfterTheRunsEndAreRefused) {
  CheckpointLimits limits;
  limits.max_stamp_s = 320.0;
  AgentCheckpoint c = Checkpoint();
  c.processed_until = 1e300;
  EXPECT_EQ(Refusal(CheckpointToJson(c), limits),
            Reason("processed_until is 1e+300 s, after the end of the run (320 s)"));
  c = Checkpoint();
  c.earlier[1].origin_stamp = 320.5;
  EXPECT_EQ(Refusal(CheckpointToJson(c), limits),
            Reason("earlier[1].origin_stamp is 320.5 s, after the end of the run (320 s)"));
  c.earlier[1].origin_stamp = 320.0;  // on the bound
  EXPECT_TRUE(Parse(CheckpointToJson(c).dump(), limits).ok());
}

TEST(Checkpoint, NanMeanIsRefused) {
  AgentCheckpoint c = Checkpoint();
  c.local.landmarks[1].mean.y() = std::nan("");
  EXPECT_EQ(Refusal(CheckpointToJson(c)),
            Reason("local.landmarks[1].y is null, expected a finite number (NaN and inf are written as null)"));
  // A NaN literal (as Python writes it) is not JSON.
  std::string text = CheckpointToJson(Checkpoint()).dump();
  text.replace(text.find("\"x\":") + 4, 1, "NaN,\"z\":");
  EXPECT_NE(Refusal(text).find(": not valid JSON: parse error"), std::string::npos);
}

TEST(Checkpoint, InfiniteCovarianceIsRefused) {
  AgentCheckpoint c = Checkpoint();
  c.earlier[1].global.landmarks[2].cov(1, 1) = std::numeric_limits<double>::infinity();
  EXPECT_EQ(Refusal(CheckpointToJson(c)),
            Reason("earlier[1].global.landmarks[2].cov[2] is null, expected a finite number (NaN and inf are "
                   "written as null)"));
  // A number too large for a double is refused by the parser.
  json doc = CheckpointToJson(Checkpoint());
  doc["local"]["landmarks"][0]["cov"][0] = 123456789.0;
  std::string text = doc.dump();
  text.replace(text.find("123456789.0"), 11, "1e999");
  EXPECT_EQ(Refusal(text), Reason("not valid JSON: number overflow parsing '1e999'"));
}

TEST(Checkpoint, CovarianceMustBePositiveSemiDefinite) {
  AgentCheckpoint c = Checkpoint();
  c.local.landmarks[0].cov << 1.0, 2.0, 2.0, 1.0;  // det -3
  EXPECT_EQ(Refusal(CheckpointToJson(c)), Reason("local.landmarks[0].cov [1, 2, 1] is not positive semi-definite"));
  c.local.landmarks[0].cov << -0.5, 0.0, 0.0, 1.0;
  EXPECT_EQ(Refusal(CheckpointToJson(c)), Reason("local.landmarks[0].cov [-0.5, 0, 1] is not positive semi-definite"));
  c.local.landmarks[0].cov << 0.0, 0.0, 0.0, 0.0;  // PSD (a perfectly known landmark) is taken
  EXPECT_TRUE(Parse(CheckpointToJson(c).dump()).ok());
}

TEST(Checkpoint, LandmarkIdsAreUniqueWithinAMap) {
  AgentCheckpoint c = Checkpoint();
  c.global.landmarks[3].id = c.global.landmarks[1].id;
  EXPECT_EQ(Refusal(CheckpointToJson(c)), Reason("global.landmarks[3].id 11 is a duplicate in global"));
  // The same id in two different maps is fine.
  c = Checkpoint();
  ASSERT_EQ(c.local.landmarks[0].id, c.global.landmarks[0].id);
  EXPECT_TRUE(Parse(CheckpointToJson(c).dump()).ok());
}

TEST(Checkpoint, CoordinatesBeyondTheWorldBoundAreRefused) {
  AgentCheckpoint c = Checkpoint();
  c.local.landmarks[2].mean.x() = -1.5e5;
  EXPECT_EQ(Refusal(CheckpointToJson(c)),
            Reason("local.landmarks[2].x is -150000 m, beyond the world bound of 100000 m"));
  c.local.landmarks[2].mean.x() = -1e5;  // on the bound
  EXPECT_TRUE(Parse(CheckpointToJson(c).dump()).ok());
}

// 100 000 nested earlier entries: refused from the text alone, before anything is built.
TEST(Checkpoint, EarlierNestedOneHundredThousandDeepIsRefused) {
  std::string text;
  const std::string open = R"({"robot":3,"incarnation":1,"origin_stamp":0,"processed_until":0,)"
                           R"("local":{"landmarks":[]},"global":{"landmarks":[]},"earlier":[)";
  for (int i = 0; i < 100000; ++i) text += open;
  for (int i = 0; i < 100000; ++i) text += "]}";
  EXPECT_EQ(Refusal(text), Reason("nested deeper than 136 levels (at most 64 earlier incarnations, nested or not)"));
  // The same without the closing brackets (truncated) is refused the same way.
  EXPECT_EQ(Refusal(text.substr(0, text.size() / 2)),
            Reason("nested deeper than 136 levels (at most 64 earlier incarnations, nested or not)"));
}

// Just past the limit, nested or flat: refused by counting, with the place named.
TEST(Checkpoint, MoreThanTheLimitOfEarlierIncarnationsIsRefused) {
  const auto entry = [](std::uint32_t inc) { return CheckpointToJson(AgentCheckpoint{Snapshot(inc, 0), {}, {}, {}}); };
  json doc = entry(1000);
  json* at = &doc;
  std::string path;
  for (std::uint32_t i = 0; i < 65; ++i) {
    (*at)["earlier"] = json::array({entry(100 + i)});
    at = &(*at)["earlier"][0];
    path += path.empty() ? "earlier[0]" : ".earlier[0]";
  }
  const std::string last = path.substr(0, path.size() - std::string(".earlier[0]").size());
  EXPECT_EQ(Refusal(doc), Reason(last + ".earlier makes more than 64 earlier incarnations in all"));
  json flat = entry(1000);
  for (std::uint32_t i = 0; i < 65; ++i) flat["earlier"].push_back(entry(100 + i));
  EXPECT_EQ(Refusal(flat), Reason("earlier makes more than 64 earlier incarnations in all"));
  flat["earlier"].erase(flat["earlier"].size() - 1);  // 64: taken
  const CheckpointLoad r = Parse(flat.dump());
  ASSERT_TRUE(r.ok()) << r.error;
  EXPECT_EQ(r.checkpoint->earlier.size(), 64u);
}

TEST(Checkpoint, MoreLandmarksThanTheLimitAreRefused) {
  CheckpointLimits limits;
  limits.max_landmarks = 3;
  AgentCheckpoint c = Checkpoint();
  EXPECT_EQ(Refusal(CheckpointToJson(c), limits),
            Reason("global.landmarks holds 5 landmarks, more than the limit of 3"));
  c.global = SomeMap(3, 0);
  c.earlier.clear();
  EXPECT_TRUE(Parse(CheckpointToJson(c).dump(), limits).ok());
  EXPECT_EQ(CheckpointLimits{}.max_landmarks, 100000u);
}

// The submaps are input like a peer's: each must decode, keep the submap limits and close
// within the run, and none may repeat an identity or be the resuming incarnation's.
TEST(Checkpoint, SubmapsAreValidatedLikeAPeersAndNamedByIdentity) {
  json doc = CheckpointToJson(Checkpoint());
  doc["submaps"] = 5;
  EXPECT_EQ(Refusal(doc), Reason("submaps is 5, expected an array"));
  doc["submaps"] = json::array({Base64Encode(SubmapBytes(5, 1, 0)), 7});
  EXPECT_EQ(Refusal(doc), Reason("submaps[1] is 7, expected a base64 string"));
  doc["submaps"][1] = "Zm9v\n";
  EXPECT_EQ(Refusal(doc), Reason("submaps[1] is not base64 (padded, the standard alphabet, no whitespace)"));
  std::vector<std::uint8_t> truncated = SubmapBytes(5, 1, 1);
  truncated.resize(truncated.size() - 4);
  doc["submaps"][1] = Base64Encode(truncated);
  EXPECT_EQ(Refusal(doc), Reason("submaps[1] is not a submap: truncated"));
  doc["submaps"][1] = Base64Encode(SubmapBytes(kRobot, kNow, 0));
  EXPECT_EQ(Refusal(doc), Reason("submaps[1] (3.9.0) is of the resuming process's own incarnation"));
  doc["submaps"][1] = Base64Encode(SubmapBytes(5, 1, 0, 2.0));  // another submap, the same identity
  EXPECT_EQ(Refusal(doc), Reason("submaps[1] repeats the identity 5.1.0 of submaps[0]"));
  doc["submaps"][1] = Base64Encode(SubmapBytes(5, 1, 1, 60.0));
  CheckpointLimits limits;
  limits.submap_limits.world_radius_m = 50.0;
  EXPECT_EQ(Refusal(doc, limits), Reason("submaps[1] (5.1.1) is beyond the limits: out_of_world"));
  limits = {};
  limits.max_stamp_s = 45.0;  // the snapshots' stamps are within it, submap 5.1.5 closes at 59 s
  doc["submaps"][1] = Base64Encode(SubmapBytes(5, 1, 5));
  EXPECT_EQ(Refusal(doc, limits), Reason("submaps[1] (5.1.5) closes at 59 s, after the end of the run (45 s)"));
  doc["submaps"][1] = Base64Encode(SubmapBytes(5, 1, 1, 60.0));
  limits = {};
  limits.max_submaps = 1;
  EXPECT_EQ(Refusal(doc, limits), Reason("submaps holds 2 submaps, more than the limit of 1"));
  limits.max_submaps = 2;
  const CheckpointLoad r = Parse(doc.dump(), limits);
  ASSERT_TRUE(r.ok()) << r.error;
  EXPECT_EQ(r.checkpoint->submaps, (std::vector<SubmapBlob>{SubmapBytes(5, 1, 0), SubmapBytes(5, 1, 1, 60.0)}));
  EXPECT_EQ(CheckpointLimits{}.max_submaps, 20000u);
}

// Issue R3: a secure run's submaps keep their signatures ({"submap", "signature"}, base64),
// unsigned ones stay strings; an entry of any other shape is refused in one line naming it.
TEST(Checkpoint, SignedSubmapsRoundTripAndMalformedOnesAreRefused) {
  AgentCheckpoint c = Checkpoint();
  c.submaps[1].signature = std::vector<std::uint8_t>(71, 0x30);
  c.submaps[3].signature = {1};
  json doc = CheckpointToJson(c);
  EXPECT_TRUE(doc["submaps"][0].is_string());
  EXPECT_EQ(doc["submaps"][1].size(), 2u);
  const CheckpointLoad back = Parse(doc.dump());
  ASSERT_TRUE(back.ok()) << back.error;
  EXPECT_EQ(back.checkpoint->submaps, c.submaps);
  const std::string bytes = Base64Encode(SubmapBytes(5, 1, 0));
  const auto refused = [&](json entry, const std::string& why) {
    json d = doc;
    d["submaps"][3] = std::move(entry);
    EXPECT_EQ(Refusal(d), Reason(why));
  };
  refused({{"submap", bytes}}, "submaps[3] has 1 keys, expected submap and signature");
  refused({{"submap", bytes}, {"sig", "AQ=="}}, "submaps[3].signature is missing");
  refused({{"submap", bytes}, {"signature", 7}}, "submaps[3].signature is 7, expected a base64 string");
  refused({{"submap", bytes}, {"signature", "A"}},
          "submaps[3].signature is not base64 (padded, the standard alphabet, no whitespace)");
  refused({{"submap", bytes}, {"signature", ""}}, "submaps[3].signature holds 0 bytes, expected 1 to 1024");
  refused({{"submap", bytes}, {"signature", Base64Encode(std::vector<std::uint8_t>(1025, 1))}},
          "submaps[3].signature holds 1025 bytes, expected 1 to 1024");
  refused({{"bytes", bytes}, {"signature", "AQ=="}}, "submaps[3].submap is missing");
  refused({{"submap", 3}, {"signature", "AQ=="}}, "submaps[3].submap is 3, expected a base64 string");
}

TEST(Checkpoint, MalformedJsonIsOneLine) {
  for (const std::string text :
       {"", "{", "[1, 2", "nul", "{\"robot\": 3,}", "\xff\xfe{}", "{\"a\":\"\n\"}", "{\"robot\": 3} trailing"}) {
    SCOPED_TRACE(text);
    EXPECT_NE(Refusal(text).find(": not valid JSON: "), std::string::npos);
  }
  // A long unterminated string does not make a long reason.
  const std::string reason = Refusal("{\"" + std::string(100000, 'a'));
  EXPECT_LT(reason.size(), 400u) << reason;
}

// Every prefix of a valid checkpoint (a write cut short) is refused, never taken in part.
TEST(Checkpoint, EveryTruncationIsRefused) {
  AgentCheckpoint c;
  static_cast<IncarnationSnapshot&>(c) = Snapshot(4, 1);
  c.earlier = {Snapshot(2, 1)};
  const std::string text = CheckpointToJson(c).dump();
  for (std::size_t n = 0; n < text.size(); ++n) {
    const CheckpointLoad r = Parse(text.substr(0, n));
    ASSERT_FALSE(r.ok()) << n;
    ASSERT_EQ(r.error.find('\n'), std::string::npos) << r.error;
  }
  EXPECT_TRUE(Parse(text).ok());
}

TEST(Checkpoint, MissingKeysAreNamed) {
  const json good = CheckpointToJson(Checkpoint());
  for (const char* key : {"robot", "incarnation", "origin_stamp", "processed_until", "local", "global"}) {
    json doc = good;
    doc.erase(key);
    EXPECT_EQ(Refusal(doc), Reason(std::string(key) + " is missing"));
    doc = good;
    doc["earlier"][1].erase(key);
    EXPECT_EQ(Refusal(doc), Reason("earlier[1]." + std::string(key) + " is missing"));
  }
  json doc = good;
  doc["global"].erase("landmarks");
  EXPECT_EQ(Refusal(doc), Reason("global.landmarks is missing"));
  for (const char* key : {"id", "x", "y", "cov"}) {
    doc = good;
    doc["earlier"][0]["local"]["landmarks"][1].erase(key);
    EXPECT_EQ(Refusal(doc), Reason("earlier[0].local.landmarks[1]." + std::string(key) + " is missing"));
  }
}

TEST(Checkpoint, WrongTypesAreNamed) {
  const json good = CheckpointToJson(Checkpoint());
  const auto with = [&](const json::json_pointer& where, const json& value) {
    json doc = good;
    doc[where] = value;
    return Refusal(doc);
  };
  using P = json::json_pointer;
  EXPECT_EQ(Refusal(json::array({good})), Reason("the document is an array of 1, expected an object"));
  EXPECT_EQ(Refusal(json("checkpoint")), Reason("the document is a string, expected an object"));
  EXPECT_EQ(with(P("/robot"), "3"), Reason("robot is a string, expected an integer >= 0"));
  EXPECT_EQ(with(P("/robot"), 3.0), Reason("robot is 3.0, expected an integer >= 0"));
  EXPECT_EQ(with(P("/incarnation"), -1), Reason("incarnation is -1, expected an integer >= 0"));
  EXPECT_EQ(with(P("/origin_stamp"), true), Reason("origin_stamp is true, expected a finite number"));
  EXPECT_EQ(with(P("/local"), json::array()), Reason("local is an array of 0, expected an object"));
  EXPECT_EQ(with(P("/global/landmarks"), json::object()), Reason("global.landmarks is an object, expected an array"));
  EXPECT_EQ(with(P("/global/shape_sigma_m"), -0.1), Reason("global.shape_sigma_m is -0.1, expected >= 0"));
  EXPECT_EQ(with(P("/earlier"), json::object()), Reason("earlier is an object, expected an array"));
  EXPECT_EQ(with(P("/earlier/1"), 7), Reason("earlier[1] is 7, expected an object"));
  EXPECT_EQ(with(P("/local/landmarks/2"), json::array()),
            Reason("local.landmarks[2] is an array of 0, expected an object"));
  EXPECT_EQ(with(P("/local/landmarks/0/id"), 4294967296ull),
            Reason("local.landmarks[0].id 4294967296 is beyond 32 bits"));
  EXPECT_EQ(with(P("/local/landmarks/0/signature"), 1.5),
            Reason("local.landmarks[0].signature is 1.5, expected a 32-bit integer"));
  EXPECT_EQ(with(P("/local/landmarks/0/signature"), -2147483649ll),
            Reason("local.landmarks[0].signature is -2147483649, expected a 32-bit integer"));
  EXPECT_EQ(with(P("/local/landmarks/0/signature"), 2147483648ull),
            Reason("local.landmarks[0].signature is 2147483648, expected a 32-bit integer"));
  EXPECT_EQ(with(P("/local/landmarks/0/x"), "1"), Reason("local.landmarks[0].x is a string, expected a finite number"));
  EXPECT_EQ(with(P("/local/landmarks/0/cov"), json::array({1, 0})),
            Reason("local.landmarks[0].cov is an array of 2, expected an array [xx, xy, yy] of 3 numbers"));
  EXPECT_EQ(with(P("/local/landmarks/0/cov/1"), json::object()),
            Reason("local.landmarks[0].cov[1] is an object, expected a finite number"));
}

class CheckpointFile : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() / ("mapmesh_checkpoint_test_" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::string Write(const std::string& text) {
    const std::string path = (dir_ / "checkpoint.json").string();
    std::ofstream(path, std::ios::binary) << text;
    return path;
  }
  std::filesystem::path dir_;
};

TEST_F(CheckpointFile, LoadsAValidFile) {
  const std::string path = Write(CheckpointToJson(Checkpoint()).dump(1));
  const CheckpointLoad r = LoadCheckpoint(path, kRobot, kNow);
  ASSERT_TRUE(r.ok()) << r.error;
  ExpectSame(*r.checkpoint, Checkpoint());
  // Errors name the path it was given.
  EXPECT_EQ(LoadCheckpoint(path, 4, kNow).error, path + ": robot is 3, expected 4");
}

TEST_F(CheckpointFile, AMissingFileIsMissingNotAnError) {
  const CheckpointLoad r = LoadCheckpoint((dir_ / "none.json").string(), kRobot, kNow);
  EXPECT_FALSE(r.ok());
  EXPECT_TRUE(r.missing);
}

TEST_F(CheckpointFile, ADirectoryIsRefused) {
  const std::string path = (dir_ / "checkpoint.json").string();
  std::filesystem::create_directories(path);
  const CheckpointLoad r = LoadCheckpoint(path, kRobot, kNow);
  EXPECT_FALSE(r.ok());
  EXPECT_FALSE(r.missing);
  EXPECT_EQ(r.error, path + ": is a directory, not a checkpoint file");
}

TEST_F(CheckpointFile, AnOversizeFileIsRefusedBeforeReading) {
  CheckpointLimits limits;
  limits.max_file_bytes = 100;
  const std::string path = Write(std::string(101, ' '));
  EXPECT_EQ(LoadCheckpoint(path, kRobot, kNow, limits).error, path + ": is 101 bytes, more than the limit of 100");
  EXPECT_EQ(CheckpointLimits{}.max_file_bytes, 256u << 20);
  // A sparse file over the default limit: refused from its size alone, nothing is read.
  std::filesystem::resize_file(path, (256u << 20) + 1);
  EXPECT_EQ(LoadCheckpoint(path, kRobot, kNow).error, path + ": is 268435457 bytes, more than the limit of 268435456");
}

}  // namespace
}  // namespace mapmesh::io
