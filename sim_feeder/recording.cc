#include "sim_feeder/recording.h"

#include <cstdio>
#include <cstring>
#include <stdexcept>

namespace mapmesh {
namespace {

constexpr char kMagic[] = "MMREC1\n";

template <typename T>
void Put(std::vector<std::uint8_t>& b, T v) {
  std::uint8_t raw[sizeof(T)];
  std::memcpy(raw, &v, sizeof(T));
  b.insert(b.end(), raw, raw + sizeof(T));
}

class Cursor {
 public:
  Cursor(const std::vector<std::uint8_t>& b, const std::string& path) : b_(b), path_(path) {}
  template <typename T>
  T Get() {
    if (pos_ + sizeof(T) > b_.size()) throw std::runtime_error(path_ + ": truncated recording");
    T v;
    std::memcpy(&v, b_.data() + pos_, sizeof(T));
    pos_ += sizeof(T);
    return v;
  }
  bool AtEnd() const { return pos_ == b_.size(); }
  std::size_t pos_ = 0;

 private:
  const std::vector<std::uint8_t>& b_;
  const std::string& path_;
};

}  // namespace

RecordingWriter::RecordingWriter(const std::string& path) : path_(path) {
  f_ = std::fopen(path.c_str(), "wb");
  if (!f_) throw std::runtime_error(path + ": cannot create recording");
  std::fwrite(kMagic, 1, sizeof(kMagic) - 1, f_);
}

RecordingWriter::~RecordingWriter() {
  if (f_) std::fclose(f_);
}

void RecordingWriter::Write(const FeedBatch& b) {
  buf_.clear();
  Put<double>(buf_, b.stamp);
  Put<std::uint32_t>(buf_, static_cast<std::uint32_t>(b.scans.size()));
  for (const Scan& s : b.scans) {
    Put(buf_, s.robot_id);
    Put(buf_, s.seq);
    Put(buf_, s.stamp);
    Put<std::uint32_t>(buf_, static_cast<std::uint32_t>(s.obs.size()));
    for (const Observation& o : s.obs) {
      Put(buf_, o.range);
      Put(buf_, o.bearing);
      Put(buf_, o.signature);
      Put<std::uint8_t>(buf_, static_cast<std::uint8_t>(o.kind));
    }
  }
  Put<std::uint32_t>(buf_, static_cast<std::uint32_t>(b.odom.size()));
  for (const Odometry& o : b.odom) {
    Put(buf_, o.robot_id);
    Put(buf_, o.seq);
    Put(buf_, o.stamp);
    Put(buf_, o.dt);
    Put(buf_, o.v);
    Put(buf_, o.w);
    Put(buf_, o.steering);
    Put(buf_, o.scans_in_interval);
  }
  Put<std::uint32_t>(buf_, static_cast<std::uint32_t>(b.truth.size()));
  for (const GroundTruth& g : b.truth) {
    Put(buf_, g.robot_id);
    Put(buf_, g.stamp);
    Put(buf_, g.x);
    Put(buf_, g.y);
    Put(buf_, g.theta);
  }
  Put<std::uint8_t>(buf_, b.links ? 1 : 0);
  if (b.links) {
    Put(buf_, b.links->stamp);
    Put<std::uint32_t>(buf_, static_cast<std::uint32_t>(b.links->links.size()));
    for (const Link& l : b.links->links) {
      Put(buf_, l.a);
      Put(buf_, l.b);
    }
  }
  if (std::fwrite(buf_.data(), 1, buf_.size(), f_) != buf_.size()) {
    throw std::runtime_error(path_ + ": write failed");
  }
}

void RecordingWriter::Close() {
  if (!f_) return;
  const bool ok = std::fflush(f_) == 0;
  std::fclose(f_);
  f_ = nullptr;
  if (!ok) throw std::runtime_error(path_ + ": write failed");
}

std::vector<FeedBatch> ReadRecording(const std::string& path) {
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (!f) throw std::runtime_error(path + ": cannot open recording");
  std::vector<std::uint8_t> bytes;
  std::uint8_t chunk[65536];
  std::size_t n;
  while ((n = std::fread(chunk, 1, sizeof chunk, f)) > 0) bytes.insert(bytes.end(), chunk, chunk + n);
  std::fclose(f);
  const std::size_t magic = sizeof(kMagic) - 1;
  if (bytes.size() < magic || std::memcmp(bytes.data(), kMagic, magic) != 0) {
    throw std::runtime_error(path + ": not a mapmesh recording");
  }
  Cursor c(bytes, path);
  c.pos_ = magic;
  std::vector<FeedBatch> out;
  while (!c.AtEnd()) {
    FeedBatch b;
    b.stamp = c.Get<double>();
    for (std::uint32_t i = 0, n_scans = c.Get<std::uint32_t>(); i < n_scans; ++i) {
      Scan s;
      s.robot_id = c.Get<RobotId>();
      s.seq = c.Get<std::uint32_t>();
      s.stamp = c.Get<double>();
      for (std::uint32_t j = 0, n_obs = c.Get<std::uint32_t>(); j < n_obs; ++j) {
        Observation o;
        o.range = c.Get<double>();
        o.bearing = c.Get<double>();
        o.signature = c.Get<std::int32_t>();
        o.kind = c.Get<std::uint8_t>() == 1 ? ObservationKind::kRobot : ObservationKind::kLandmark;
        s.obs.push_back(o);
      }
      b.scans.push_back(std::move(s));
    }
    for (std::uint32_t i = 0, n_odom = c.Get<std::uint32_t>(); i < n_odom; ++i) {
      Odometry o;
      o.robot_id = c.Get<RobotId>();
      o.seq = c.Get<std::uint32_t>();
      o.stamp = c.Get<double>();
      o.dt = c.Get<double>();
      o.v = c.Get<double>();
      o.w = c.Get<double>();
      o.steering = c.Get<double>();
      o.scans_in_interval = c.Get<std::uint32_t>();
      b.odom.push_back(o);
    }
    for (std::uint32_t i = 0, n_truth = c.Get<std::uint32_t>(); i < n_truth; ++i) {
      GroundTruth g;
      g.robot_id = c.Get<RobotId>();
      g.stamp = c.Get<double>();
      g.x = c.Get<double>();
      g.y = c.Get<double>();
      g.theta = c.Get<double>();
      b.truth.push_back(g);
    }
    if (c.Get<std::uint8_t>()) {
      RadioLinks l;
      l.stamp = c.Get<double>();
      for (std::uint32_t i = 0, n_links = c.Get<std::uint32_t>(); i < n_links; ++i) {
        const RobotId a = c.Get<RobotId>();
        l.links.push_back({a, c.Get<RobotId>()});
      }
      b.links = std::move(l);
    }
    out.push_back(std::move(b));
  }
  return out;
}

}  // namespace mapmesh
