// fuzz_corpus OUT_DIR SOURCE_DIR: writes the fuzz targets' seed corpora and dictionaries
// (OUT_DIR/<target>/ and OUT_DIR/<target>.dict), so that no corpus is committed. Map seeds are
// real encodings (EncodeMap) of seeded random maps plus edge cases; checkpoint seeds are
// CheckpointToJson documents, nested and flat, plus bad cases; scenario seeds are the shipped
// scenarios (SOURCE_DIR/scenarios, tests/integration/data) plus variants with overrides.
// Earlier seeds are replaced; other files (inputs that fuzzing found, named by their SHA-1) stay.

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/io/checkpoint.h"
#include "common/map/landmark_map.h"
#include "common/map/map_codec.h"
#include "common/map/submap_codec.h"

namespace mapmesh {
namespace {

namespace fs = std::filesystem;
using Bytes = std::vector<std::uint8_t>;

// The resuming process that fuzz/checkpoint_fuzz.cc parses for.
constexpr RobotId kRobot = 3;
constexpr std::uint32_t kIncarnation = 7;

void Write(const fs::path& path, std::string_view data) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(data.data(), static_cast<std::streamsize>(data.size()));
  if (!out) {
    std::fprintf(stderr, "fuzz_corpus: cannot write %s\n", path.c_str());
    std::exit(1);
  }
}

void WriteBytes(const fs::path& path, const Bytes& b) {
  Write(path, std::string_view(reinterpret_cast<const char*>(b.data()), b.size()));
}

std::string ReadText(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// A libFuzzer dictionary entry: the bytes quoted, anything unprintable as \xNN.
std::string DictEntry(std::string_view bytes) {
  std::string out = "\"";
  for (const char c : bytes) {
    const auto u = static_cast<unsigned char>(c);
    if (u >= 0x20 && u < 0x7f && c != '"' && c != '\\') {
      out += c;
    } else {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\x%02X", u);
      out += buf;
    }
  }
  return out + "\"";
}

void WriteDict(const fs::path& path, const std::set<std::string>& entries) {
  std::string text;
  for (const std::string& e : entries) text += DictEntry(e) + "\n";
  Write(path, text);
}

// Every string literal that looks like a key or a choice ("max_range_m", "cekf") in a source.
std::set<std::string> KeyLiterals(const fs::path& source) {
  const std::string text = ReadText(source);
  const std::regex literal("\"([a-z][a-z0-9_]*)\"");
  std::set<std::string> keys;
  for (auto it = std::sregex_iterator(text.begin(), text.end(), literal); it != std::sregex_iterator(); ++it) {
    keys.insert((*it)[1].str());
  }
  return keys;
}

// The backticked names of docs/SCENARIOS.md (keys, their dotted parts, choices), lower-case
// identifiers only.
std::set<std::string> DocumentedNames(const fs::path& docs) {
  const std::string text = ReadText(docs);
  const std::regex quoted("`([a-z][a-z0-9_.\\[\\]]*)`"), part("[a-z][a-z0-9_]*");
  std::set<std::string> names;
  for (auto it = std::sregex_iterator(text.begin(), text.end(), quoted); it != std::sregex_iterator(); ++it) {
    const std::string name = (*it)[1].str();
    for (auto p = std::sregex_iterator(name.begin(), name.end(), part); p != std::sregex_iterator(); ++p) {
      names.insert(p->str());
    }
  }
  return names;
}

// A random map: n landmarks within `extent` m of the origin, standard deviations from 10 um to
// 3 km, any correlation.
LandmarkMap RandomMap(std::size_t n, double extent, std::mt19937& rng) {
  std::uniform_real_distribution<double> pos(-extent, extent), log_sigma(std::log(1e-5), std::log(3e3)),
      rho(-0.9999, 0.9999);
  LandmarkMap map;
  std::uniform_int_distribution<std::uint32_t> id;
  std::set<std::uint32_t> ids;
  while (map.size() < n) {
    Landmark l;
    l.id = n < 50 ? static_cast<std::uint32_t>(map.size()) : id(rng);
    if (!ids.insert(l.id).second) continue;
    l.mean = {pos(rng), pos(rng)};
    const double sx = std::exp(log_sigma(rng)), sy = std::exp(log_sigma(rng)), r = rho(rng);
    l.cov << sx * sx, r * sx * sy, r * sx * sy, sy * sy;
    map.landmarks.push_back(l);
  }
  return map;
}

Bytes Encode(const LandmarkMap& map) {
  MapDecodeError error = MapDecodeError::kOk;
  Bytes b = EncodeMap(map, &error);
  if (error != MapDecodeError::kOk) {
    std::fprintf(stderr, "fuzz_corpus: a seed map does not encode: %s\n", std::string(ToString(error)).c_str());
    std::exit(1);
  }
  return b;
}

template <typename T>
void Poke(Bytes& b, std::size_t at, T v) {
  std::memcpy(b.data() + at, &v, sizeof v);
}

void MapSeeds(const fs::path& dir) {
  std::mt19937 rng(20240601);
  int k = 0;
  const auto add = [&](const std::string& what, const Bytes& b) {
    char name[64];
    std::snprintf(name, sizeof name, "seed-%03d-%s", k++, what.c_str());
    WriteBytes(dir / name, b);
  };
  // Valid maps of various sizes, extents and shape precisions.
  for (const std::size_t n : {0, 1, 2, 3, 8, 32, 100, 250}) {
    for (const double extent : {0.5, 50.0, 7999.0}) {
      LandmarkMap map = RandomMap(n, extent, rng);
      map.shape_sigma_m = n % 3 == 0 ? 0.0 : 0.01 * static_cast<double>(n);
      add("valid-" + std::to_string(n) + "-" + std::to_string(static_cast<int>(extent)), Encode(map));
    }
  }
  // Edge values: the coordinate bound, extreme and clamped sigmas, extreme correlations, ids.
  LandmarkMap edge;
  const double b = kMapCodecMaxCoordinateM;
  const std::vector<std::array<double, 5>> rows = {{b, b, 1e-5, 1e-5, 0.0},       {-b, -b, 3.4e3, 3.4e3, 0.9999},
                                                   {b, -b, 1e-9, 1e4, -0.9999},   {0, 0, 1e-5, 3.4e3, 1.0},
                                                   {-0.0, 0.0005, 0.0, 0.0, 0.0}, {1e-3, -1e-3, 1, 1, -1.0}};
  for (std::size_t i = 0; i < rows.size(); ++i) {
    Landmark l;
    l.id = i == 0 ? 0 : i == 1 ? std::numeric_limits<std::uint32_t>::max() : static_cast<std::uint32_t>(i * 1000);
    l.mean = {rows[i][0], rows[i][1]};
    const double sx = rows[i][2], sy = rows[i][3], r = rows[i][4];
    l.cov << sx * sx, r * sx * sy, r * sx * sy, sy * sy;
    edge.landmarks.push_back(l);
  }
  edge.shape_sigma_m = std::numeric_limits<float>::max();
  const Bytes e = Encode(edge);
  add("edge", e);
  edge.shape_sigma_m = 1e-40;  // a subnormal float
  add("edge-subnormal-shape", Encode(edge));

  // Malformed payloads, one per reason (and a few boundaries).
  const Bytes one = Encode(RandomMap(1, 10.0, rng));
  const Bytes two = Encode(RandomMap(2, 10.0, rng));
  add("empty", {});
  add("short", {'M', 'M', 2});
  add("header-only", Bytes(one.begin(), one.begin() + kMapCodecHeaderBytes));
  add("truncated", Bytes(one.begin(), one.end() - 1));
  Bytes x = one;
  x.push_back(0);
  add("oversized", x);
  x = one;
  x[0] = 'X';
  add("bad-magic", x);
  x = one;
  x[2] = 1;
  add("version-1", x);
  x = one;
  x[3] = 1;
  add("flags", x);
  x = Bytes(one.begin(), one.begin() + kMapCodecHeaderBytes);
  Poke<std::uint32_t>(x, 4, kMapCodecMaxLandmarks + 1);
  add("count-over-limit", x);
  x = one;
  Poke<float>(x, 16, std::numeric_limits<float>::quiet_NaN());
  add("nan-shape", x);
  x = one;
  Poke<float>(x, 16, std::numeric_limits<float>::infinity());
  add("inf-shape", x);
  x = one;
  Poke<float>(x, 16, -1.0f);
  add("negative-shape", x);
  x = one;
  Poke<float>(x, 16, -0.0f);
  add("negative-zero-shape", x);
  x = one;
  Poke<std::int32_t>(x, 8, 8000001);
  add("origin-out", x);
  x = one;
  Poke<std::int32_t>(x, 8, 8000000);
  x[kMapCodecHeaderBytes + 4] = 1;  // dx = 1 mm beyond
  x[kMapCodecHeaderBytes + 5] = 0;
  x[kMapCodecHeaderBytes + 6] = 0;
  add("landmark-out", x);
  for (const std::uint16_t code : {65534, 65535}) {
    x = one;
    Poke<std::uint16_t>(x, kMapCodecHeaderBytes + 10, code);
    add("sigma-code-" + std::to_string(code), x);
  }
  for (const std::int16_t code : {32766, 32767, -32767, -32768}) {
    x = one;
    Poke<std::int16_t>(x, kMapCodecHeaderBytes + 14, code);
    add("rho-code-" + std::to_string(code), x);
  }
  x = two;
  std::memcpy(x.data() + kMapCodecHeaderBytes + kMapCodecLandmarkBytes, x.data() + kMapCodecHeaderBytes, 4);
  add("duplicate-id", x);

  // Raw maps, as the target's encoder check reads its bytes (44 bytes a landmark, then shape).
  const auto raw = [](const LandmarkMap& map) {
    Bytes b;
    for (const Landmark& l : map.landmarks) {
      const double v[5] = {l.mean.x(), l.mean.y(), l.cov(0, 0), l.cov(0, 1), l.cov(1, 1)};
      b.insert(b.end(), reinterpret_cast<const std::uint8_t*>(&l.id), reinterpret_cast<const std::uint8_t*>(&l.id) + 4);
      b.insert(b.end(), reinterpret_cast<const std::uint8_t*>(v), reinterpret_cast<const std::uint8_t*>(v) + sizeof v);
    }
    const double shape = map.shape_sigma_m;
    b.insert(b.end(), reinterpret_cast<const std::uint8_t*>(&shape), reinterpret_cast<const std::uint8_t*>(&shape) + 8);
    return b;
  };
  for (const std::size_t n : {1, 3, 20}) add("raw-" + std::to_string(n), raw(RandomMap(n, 100.0, rng)));
  add("raw-edge", raw(edge));
  LandmarkMap beyond = edge;
  beyond.landmarks[0].mean.x() = kMapCodecMaxCoordinateM + 0.0005;  // rounds beyond the bound
  beyond.landmarks[1].cov(0, 1) = 1e300;                            // not PSD
  add("raw-invalid", raw(beyond));

  WriteDict(dir.parent_path() / "map_decoder.dict",
            {std::string("MM\x02\x00", 4), std::string("\xff\xff", 2), std::string("\xfe\xff", 2),
             std::string("\xfe\x7f", 2), std::string("\xff\x7f", 2), std::string("\x01\x80", 2),
             std::string("\x00\x80", 2), std::string("\x00\x12\x7a\x00", 4), std::string("\x00\xee\x85\xff", 4),
             std::string("\xa0\x86\x01\x00", 4), std::string("\x00\x00\xc0\x7f", 4), std::string("\x00\x00\x80\x7f", 4),
             std::string("\xff\xff\x7f\x00", 3)});
}

IncarnationSnapshot Snapshot(std::uint32_t incarnation, std::size_t n, std::mt19937& rng) {
  IncarnationSnapshot s;
  s.robot = kRobot;
  s.incarnation = incarnation;
  s.origin_stamp = 12.5 * incarnation;
  s.processed_until = s.origin_stamp + 30.25;
  s.local = RandomMap(n, 40.0, rng);
  s.global = RandomMap(n + n / 2, 60.0, rng);
  s.local.shape_sigma_m = 0.02;
  for (std::size_t i = 0; i < s.local.size(); ++i) s.local.landmarks[i].signature = static_cast<std::int32_t>(i) - 1;
  return s;
}

void CheckpointSeeds(const fs::path& dir, const fs::path& source_dir) {
  using nlohmann::json;
  std::mt19937 rng(20240602);
  int k = 0;
  const auto add = [&](const std::string& what, const std::string& text) {
    char name[64];
    std::snprintf(name, sizeof name, "seed-%03d-%s.json", k++, what.c_str());
    Write(dir / name, text);
  };
  AgentCheckpoint c;
  static_cast<IncarnationSnapshot&>(c) = Snapshot(5, 3, rng);
  add("no-earlier", io::CheckpointToJson(c).dump());
  AgentCheckpoint empty;
  empty.robot = kRobot;
  add("empty-maps", io::CheckpointToJson(empty).dump());
  c.earlier = {Snapshot(1, 2, rng), Snapshot(2, 0, rng), Snapshot(4, 1, rng)};
  const json flat = io::CheckpointToJson(c);
  add("flat", flat.dump());
  add("flat-pretty", flat.dump(2));
  // Older files nest earlier[] inside earlier entries.
  json nested = flat;
  json inner = nested["earlier"][2];
  nested["earlier"][1]["earlier"] = json::array({inner});
  nested["earlier"].erase(2);
  json deepest = nested["earlier"][1];
  nested["earlier"][0]["earlier"] = json::array({deepest});
  nested["earlier"].erase(1);
  add("nested", nested.dump());
  AgentCheckpoint big;
  static_cast<IncarnationSnapshot&>(big) = Snapshot(9, 40, rng);
  add("forty-landmarks", io::CheckpointToJson(big).dump());
  AgentCheckpoint many;
  many.robot = kRobot;
  many.incarnation = 100;
  for (std::uint32_t i = 0; i < 66; ++i) {
    IncarnationSnapshot s;
    s.robot = kRobot;
    s.incarnation = i == kIncarnation ? 1000 : i;
    many.earlier.push_back(s);
  }
  add("too-many-earlier", io::CheckpointToJson(many).dump());
  // With submaps (issue J1): its own earlier chain and a peer's, each a small exact submap.
  AgentCheckpoint held = c;
  for (const SubmapId id : {SubmapId{kRobot, 5, 0}, SubmapId{kRobot, 5, 1}, SubmapId{2, 1, 0}}) {
    WireSubmap s;
    s.id = id;
    s.opened_s = 10.0 * id.index;
    s.closed_s = s.opened_s + 9.5;
    s.keys = {4, 9};
    s.x = Eigen::VectorXd::LinSpaced(7, -3.0, 3.0);
    s.SetCovariance(0.01 * Eigen::MatrixXd::Identity(7, 7));
    held.submaps.push_back(EncodeSubmap(s));
  }
  add("submaps", io::CheckpointToJson(held).dump());
  // ... and signed, as a secure run's (issue R3): a 64-byte signature on one of them.
  held.submaps[2].signature = std::vector<std::uint8_t>(64, 0x5a);
  add("signed-submaps", io::CheckpointToJson(held).dump());
  // ... with the peers' frames it had placed (issue R3).
  AgentCheckpoint placed = c;
  for (std::uint32_t i = 0; i < 3; ++i) {
    PeerAlignment a;
    a.robot = 2 + i % 2;
    a.incarnation = 1 + i;
    a.origin_stamp = 0.5 * i;
    a.frame_stamp = 0.25;
    a.to_own = {10.0 * i - 5.0, 3.0, 0.4 * i - 1.0};
    a.cov << 0.01, 0.002, 0.0, 0.002, 0.02, 0.0, 0.0, 0.0, 0.001;
    placed.peers.push_back(a);
  }
  add("peers", io::CheckpointToJson(placed).dump());

  // Bad cases, one per reason.
  const auto variant = [&](const std::string& what, auto change) {
    json j = flat;
    change(j);
    add(what, j.dump());
  };
  variant("wrong-robot", [](json& j) { j["robot"] = 4; });
  variant("own-incarnation", [](json& j) { j["incarnation"] = kIncarnation; });
  variant("repeated-incarnation", [](json& j) { j["earlier"][1]["incarnation"] = 1; });
  variant("negative-robot", [](json& j) { j["robot"] = -3; });
  variant("incarnation-beyond-32-bits", [](json& j) { j["incarnation"] = 1ull << 33; });
  variant("string-robot", [](json& j) { j["robot"] = "3"; });
  variant("nan-stamp", [](json& j) { j["origin_stamp"] = nullptr; });
  variant("negative-stamp", [](json& j) { j["processed_until"] = -1.0; });
  variant("nan-cov", [](json& j) { j["local"]["landmarks"][0]["cov"][1] = nullptr; });
  variant("non-psd", [](json& j) { j["local"]["landmarks"][0]["cov"] = {1.0, 2.0, 1.0}; });
  variant("cov-of-two", [](json& j) { j["local"]["landmarks"][0]["cov"] = {1.0, 0.0}; });
  variant("duplicate-id", [](json& j) { j["local"]["landmarks"][1]["id"] = j["local"]["landmarks"][0]["id"]; });
  variant("id-beyond-32-bits", [](json& j) { j["global"]["landmarks"][0]["id"] = 1ull << 32; });
  variant("signature-beyond-32-bits", [](json& j) { j["local"]["landmarks"][0]["signature"] = 1ll << 31; });
  variant("float-signature", [](json& j) { j["local"]["landmarks"][0]["signature"] = 1.5; });
  variant("out-of-world", [](json& j) { j["global"]["landmarks"][0]["x"] = 1e6; });
  variant("negative-shape", [](json& j) { j["local"]["shape_sigma_m"] = -0.5; });
  variant("missing-global", [](json& j) { j.erase("global"); });
  variant("missing-landmarks", [](json& j) { j["local"].erase("landmarks"); });
  variant("earlier-object", [](json& j) { j["earlier"] = json::object(); });
  variant("earlier-entry-array", [](json& j) { j["earlier"][0] = json::array(); });
  const auto peer_variant = [&](const std::string& what, auto change) {
    json j = io::CheckpointToJson(placed);
    change(j["peers"][1]);
    add(what, j.dump());
  };
  peer_variant("peer-own-robot", [](json& p) { p["robot"] = kRobot; });
  peer_variant("peer-repeated", [](json& p) {
    p["incarnation"] = 1;
    p["robot"] = 2;
  });
  peer_variant("peer-nan-theta", [](json& p) { p["theta"] = nullptr; });
  peer_variant("peer-asymmetric-cov", [](json& p) { p["cov"][1] = 1.0; });
  peer_variant("peer-short-cov", [](json& p) { p["cov"] = {1.0, 0.0, 1.0}; });
  const std::string text = flat.dump();
  add("truncated", text.substr(0, text.size() / 2));
  add("not-json", "checkpoint");
  add("number", "3");
  add("deep", std::string(200, '[') + std::string(200, ']'));
  add("deep-in-string", "{\"robot\": \"" + std::string(300, '[') + "\"}");
  add("big-number", "{\"robot\": 1e400}");
  add("bad-utf8", "{\"robot\": \"\xff\xfe\"}");

  std::set<std::string> dict = KeyLiterals(source_dir / "common/io/checkpoint.cc");
  // clang-format off
  for (const char* t : {"{", "}", "[", "]", ":", ",", "null", "true", "false", "-0.0", "1e308", "1e-320",
                        "18446744073709551615", "4294967295", "4294967296", "-2147483648", "2147483648",
                        "\"earlier\":[", "\"cov\":[1,0,1]", "\\u0000", "\"\\ud800\""}) {
    dict.insert(t);
  }
  // clang-format on
  WriteDict(dir.parent_path() / "checkpoint.dict", dict);
}

void ScenarioSeeds(const fs::path& dir, const fs::path& source_dir) {
  std::vector<fs::path> files;
  for (const char* sub : {"scenarios", "tests/integration/data"}) {
    for (const auto& e : fs::directory_iterator(source_dir / sub)) {
      if (e.path().extension() == ".yaml") files.push_back(e.path());
    }
  }
  std::sort(files.begin(), files.end());
  if (files.empty()) {
    std::fprintf(stderr, "fuzz_corpus: no scenarios under %s\n", source_dir.c_str());
    std::exit(1);
  }
  for (const fs::path& f : files) {
    const std::string prefix = f.parent_path().filename() == "data" ? "test-" : "shipped-";
    Write(dir / (prefix + f.filename().string()), ReadText(f));
  }
  // Variants: the directives the target reads, a landmark CSV, generators, path types.
  const std::string circle = ReadText(source_dir / "scenarios/thesis_circle_pair.yaml");
  Write(dir / "variant-set.yaml", circle + "#--set robots.list[1].sensor.sigma_bearing_deg=2.5\n"
                                           "#--set radio.range_m=30\n#--agents 3\n");
  Write(dir / "variant-set-map.yaml", circle + "#--set agent={slam: ekf, fusion: ci_det}\n");
  Write(dir / "variant-bad-set.yaml", circle + "#--set robots.list[5].id=9\n");
  Write(dir / "variant-csv.yaml", "version: 1\nworld:\n  landmarks:\n    csv: landmarks.csv\nrobots:\n  count: 2\n"
                                  "  defaults:\n    path: {type: lawnmower, area_m: [0, 0, 20, 20], spacing_m: 4}\n");
  Write(dir / "variant-bad-csv.yaml", "version: 1\nworld: {landmarks: {csv: bad.csv}}\nrobots: {count: 1}\n");
  Write(dir / "variant-list.yaml",
        "version: 1\nseed: 7\nduration_s: 5\nworld:\n  landmarks:\n    list: [[0, 0], [1, 2], [3, -4]]\n"
        "  bounds_m: [-10, -10, 10, 10]\nrobots:\n  list:\n    - id: 4\n      start: [0, 0, 90]\n"
        "      preset: downs\n      path: {type: waypoints, points: [[1, 1], [2, 2]], loop: false}\n"
        "    - id: 2\n      path: {type: random, count: 3, area_m: [0, 0, 5, 5]}\n");
  Write(dir / "variant-disc.yaml",
        "version: 1\nworld:\n  landmarks:\n    generator: {type: disc, count: 30, center_m: [5, 5], radius_m: 20}\n"
        "robots:\n  count: 2\n  defaults:\n    path: {type: circle, radius_m: 5, clockwise: true}\n"
        "agent: {max_stamp_jump_s: 1.0}\nfeeder: {lockstep_window_s: 0.5}\n");
  Write(dir / "variant-park.yaml",
        "version: 1\nworld:\n  landmarks:\n    generator: {type: park, count: 50, area_m: [0, 0, 80, 60], paths: 3,"
        " path_width_m: 3, scatter_fraction: 0.1}\nrobots:\n  count: 3\n  defaults:\n    path: {type: park}\n");
  Write(
      dir / "variant-anchors.yaml",
      "version: 1\nworld:\n  landmarks:\n    list: &pts [[0, 0], [5, 5]]\nrobots:\n  list:\n"
      "    - &r {id: 1, path: {type: waypoints, points: *pts}}\n    - id: 2\n      path: {type: waypoints, points: *pts}\n");
  Write(dir / "variant-empty.yaml", "");
  Write(dir / "variant-agents-only.yaml", "version: 1\nworld: {landmarks: {list: []}}\n#--agents 2\n");

  // Every key name and choice the docs list (the agent's keys are read in its modules' headers,
  // the others in the config sources; docs/SCENARIOS.md names them all, as a unit test checks).
  std::set<std::string> dict = DocumentedNames(source_dir / "docs/SCENARIOS.md");
  // clang-format off
  for (const char* t : {": ", "- ", "{", "}", "[", "]", ", ", "\n  ", "&a ", "*a", "!!str ", "!!int ", "---\n",
                        "? ", "|\n", ">\n", "~", "null", "true", "1e308", ".inf", ".nan", "-0", "0x7fffffff",
                        "2147483647", "4294967296", "#--set ", "#--agents ", "landmarks.csv", "bad.csv"}) {
    dict.insert(t);
  }
  // clang-format on
  WriteDict(dir.parent_path() / "scenario.dict", dict);
}

}  // namespace
}  // namespace mapmesh

namespace mapmesh {
namespace {

// Submap seeds: encodings (EncodeSubmap) of seeded random submaps of 0-40 landmarks, plus
// payloads refused for each reason.
void SubmapSeeds(const fs::path& dir) {
  std::mt19937 rng(20261127);
  std::normal_distribution<double> g;
  int k = 0;
  const auto add = [&](const std::string& what, const Bytes& b) {
    char name[64];
    std::snprintf(name, sizeof name, "seed-%03d-%s", k++, what.c_str());
    WriteBytes(dir / name, b);
  };
  const auto random_submap = [&](std::uint32_t n) {
    WireSubmap s;
    s.id = {static_cast<RobotId>(1 + rng() % 8), static_cast<std::uint32_t>(1 + rng() % 3),
            static_cast<std::uint32_t>(rng() % 50)};
    s.opened_s = 10.0 * (rng() % 30);
    s.closed_s = s.opened_s + 1.0 + rng() % 20;
    const auto m = static_cast<Eigen::Index>(3 + 2 * n);
    s.x.resize(m);
    for (Eigen::Index i = 0; i < m; ++i) s.x(i) = 20.0 * g(rng);
    for (std::uint32_t i = 0; i < n; ++i) s.keys.push_back(3 * i + rng() % 3);
    Eigen::MatrixXd a(m, m);
    for (Eigen::Index i = 0; i < a.size(); ++i) a.data()[i] = 0.05 * g(rng);
    s.SetCovariance(a * a.transpose() + 1e-4 * Eigen::MatrixXd::Identity(m, m));
    return s;
  };
  Bytes one;
  for (const std::uint32_t n : {0u, 1u, 2u, 5u, 12u, 40u}) {
    const Bytes b = EncodeSubmap(random_submap(n));
    if (n == 2) one = b;
    add("submap-" + std::to_string(n), b);
  }
  Bytes x = one;
  x.pop_back();
  add("truncated", x);
  x = one;
  x.push_back(0);
  add("oversized", x);
  x = one;
  x[2] = 2;
  add("version", x);
  x = one;
  Poke<double>(x, 24, -1.0);  // closed before it opened
  add("stamps", x);
  x = one;
  Poke<std::uint32_t>(x, kSubmapCodecHeaderBytes + 4, 0);  // both ids 0
  Poke<std::uint32_t>(x, kSubmapCodecHeaderBytes, 0);
  add("duplicate-id", x);
  x = one;
  Poke<float>(x, kSubmapCodecHeaderBytes + 4 * 2 + 8 * 7, -1.0f);  // L(0, 0)
  add("covariance", x);
  x = one;
  Poke<double>(x, kSubmapCodecHeaderBytes + 4 * 2 + 8 * 3, 9000.0);
  add("out-of-bounds", x);
  WriteDict(dir.parent_path() / "submap_decoder.dict",
            {std::string("MS\x01\x00", 4), std::string("\x00\x00\x80\x7f", 4), std::string("\x00\x00\x80\xbf", 4),
             std::string("\x00\x00\x00\x00\x00\x00\xf8\x7f", 8), std::string("\xf4\x01\x00\x00", 4)});
}

}  // namespace
}  // namespace mapmesh

int main(int argc, char** argv) {
  namespace fs = std::filesystem;
  if (argc != 3) {
    const bool help = argc == 2 && std::string(argv[1]) == "--help";
    std::fprintf(help ? stdout : stderr,
                 "usage: fuzz_corpus OUT_DIR SOURCE_DIR  (writes OUT_DIR/<target>/ and OUT_DIR/<target>.dict)\n");
    return help ? 0 : 2;
  }
  const fs::path out = argv[1], source = argv[2];
  for (const char* t : {"map_decoder", "submap_decoder", "checkpoint", "scenario"}) {
    fs::create_directories(out / t);
    for (const auto& e : fs::directory_iterator(out / t)) {
      const std::string name = e.path().filename().string();
      for (const char* prefix : {"seed-", "shipped-", "test-", "variant-"}) {
        if (name.starts_with(prefix)) fs::remove(e.path());
      }
    }
  }
  mapmesh::MapSeeds(out / "map_decoder");
  mapmesh::SubmapSeeds(out / "submap_decoder");
  mapmesh::CheckpointSeeds(out / "checkpoint", source);
  mapmesh::ScenarioSeeds(out / "scenario", source);
  std::printf("fuzz_corpus: seed corpora and dictionaries written to %s\n", out.c_str());
  return 0;
}
