#include "common/config/yaml_reader.h"

#include <charconv>
#include <cmath>
#include <iomanip>
#include <map>
#include <regex>
#include <sstream>

namespace mapmesh {

std::string FormatNumber(double v) {
  std::ostringstream s;
  s << std::setprecision(15) << v;
  return s.str();
}

YamlReader::YamlReader(YAML::Node node, std::string path, std::shared_ptr<const YamlSource> source)
    : node_(std::move(node)), path_(std::move(path)), source_(std::move(source)) {
  if (node_ && !node_.IsNull() && !node_.IsMap()) {
    FailAt(node_, path_, "expected a mapping of keys");
  }
  if (!node_ || !node_.IsMap()) return;
  std::map<std::string, int> first_line;
  for (const auto& kv : node_) {
    if (!kv.first.IsScalar()) {
      FailInFile(kv.first, path_, "a key must be a plain name, not a list, a mapping or null");
    }
    const std::string& key = kv.first.Scalar();
    const auto [it, inserted] = first_line.emplace(key, LineOf(kv.first));
    if (!inserted) {
      FailInFile(kv.first, KeyPath(key), "duplicate key (first given on line " + std::to_string(it->second) + ")");
    }
  }
}

int YamlReader::LineOf(const YAML::Node& node) const {
  if (node && node.Mark().line >= 0) return node.Mark().line + 1;
  if (node_ && node_.Mark().line >= 0) return node_.Mark().line + 1;
  return 1;
}

void YamlReader::FailAt(const YAML::Node& node, const std::string& key_path, const std::string& reason) const {
  const std::string shown = key_path.empty() ? "(top level)" : key_path;
  // A key set with --set (or anything below it) is reported as such: its line is not in the file.
  for (const std::string& o : source_->overridden) {
    if (key_path == o || key_path.rfind(o + ".", 0) == 0 || key_path.rfind(o + "[", 0) == 0) {
      throw ConfigError(source_->file + ": --set " + shown + ": " + reason);
    }
  }
  FailInFile(node, key_path, reason);
}

void YamlReader::FailInFile(const YAML::Node& node, const std::string& key_path, const std::string& reason) const {
  const std::string shown = key_path.empty() ? "(top level)" : key_path;
  throw ConfigError(source_->file + ":" + std::to_string(LineOf(node)) + ": " + shown + ": " + reason);
}

void YamlReader::Fail(const std::string& key, const std::string& reason) const {
  YAML::Node n;
  if (node_ && node_.IsMap() && node_[key]) n = node_[key];
  FailAt(n, KeyPath(key), reason);
}

bool YamlReader::Has(const std::string& key) const {
  return node_ && node_.IsMap() && node_[key] && !node_[key].IsNull();
}

YAML::Node YamlReader::Raw(const std::string& key) {
  MarkRead(key, /*leaf=*/true);
  if (!node_ || !node_.IsMap()) return YAML::Node();
  const YAML::Node n = node_[key];
  if (n && !n.IsNull()) {
    YAML::Emitter flow;
    flow.SetMapFormat(YAML::Flow);
    flow.SetSeqFormat(YAML::Flow);
    flow << n;
    Resolve(key, ResolvedValue::Kind::kYaml, flow.c_str());
  }
  return n ? n : YAML::Node();
}

namespace {

// The shortest text that reads back to v (std::to_chars), as JSON and YAML read numbers.
template <typename T>
std::string ShortestText(T v) {
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}

template <typename T>
ResolvedValue ValueOf(const T& v) {
  if constexpr (std::is_same_v<T, bool>) {
    return {ResolvedValue::Kind::kBool, v ? "true" : "false"};
  } else if constexpr (std::is_same_v<T, std::string>) {
    return {ResolvedValue::Kind::kString, v};
  } else {
    return {ResolvedValue::Kind::kNumber, ShortestText(v)};
  }
}

}  // namespace

template <typename T>
void YamlReader::GetScalar(const std::string& key, T& out, const char* type_name) {
  MarkRead(key, /*leaf=*/true);
  if (Has(key)) {
    const YAML::Node n = node_[key];
    if (!n.IsScalar()) Fail(key, std::string("expected ") + type_name);
    try {
      out = n.as<T>();
    } catch (const YAML::Exception&) {
      Fail(key, std::string("expected ") + type_name + ", got '" + n.Scalar() + "'");
    }
  }
  const ResolvedValue v = ValueOf(out);
  Resolve(key, v.kind, v.text);
}

void YamlReader::Resolve(const std::string& key, ResolvedValue::Kind kind, std::string text) const {
  if (source_->resolved != nullptr) (*source_->resolved)[KeyPath(key)] = {kind, std::move(text)};
}

void YamlReader::Get(const std::string& key, double& out) {
  GetScalar(key, out, "a number");
  if (Has(key) && !std::isfinite(out)) Fail(key, "must be finite");
}
void YamlReader::Get(const std::string& key, int& out) { GetScalar(key, out, "an integer"); }
void YamlReader::Get(const std::string& key, std::uint64_t& out) {
  if (Has(key) && node_[key].IsScalar() && !node_[key].Scalar().empty() && node_[key].Scalar()[0] == '-') {
    Fail(key, "must be a non-negative integer");
  }
  GetScalar(key, out, "a non-negative integer");
}
void YamlReader::Get(const std::string& key, bool& out) { GetScalar(key, out, "true or false"); }
void YamlReader::Get(const std::string& key, std::string& out) { GetScalar(key, out, "a string"); }

void YamlReader::GetVector(const std::string& key, std::vector<double>& out, std::size_t expected_len) {
  MarkRead(key, /*leaf=*/true);
  if (!Has(key)) {
    ResolveList(key, out);
    return;
  }
  const YAML::Node n = node_[key];
  if (!n.IsSequence() || n.size() != expected_len) {
    Fail(key, "expected a list of " + std::to_string(expected_len) + " numbers");
  }
  std::vector<double> v;
  for (const auto& e : n) {
    try {
      v.push_back(e.as<double>());
    } catch (const YAML::Exception&) {
      Fail(key, "expected a list of " + std::to_string(expected_len) + " numbers");
    }
    if (!std::isfinite(v.back())) Fail(key, "values must be finite");
  }
  out = std::move(v);
  ResolveList(key, out);
}

void YamlReader::ResolveList(const std::string& key, const std::vector<double>& v) const {
  std::string text = "[";
  for (std::size_t i = 0; i < v.size(); ++i) text += (i ? ", " : "") + ShortestText(v[i]);
  Resolve(key, ResolvedValue::Kind::kYaml, text + "]");
}

void YamlReader::GetChoice(const std::string& key, std::string& out, const std::vector<std::string>& choices) {
  Get(key, out);
  for (const auto& c : choices) {
    if (out == c) return;
  }
  std::string list;
  for (const auto& c : choices) list += (list.empty() ? "" : ", ") + c;
  Fail(key, "must be one of " + list + " (got '" + out + "')");
}

void YamlReader::GetInRange(const std::string& key, double& out, double lo, double hi) {
  Get(key, out);
  CheckRange(key, out, lo, hi);
}
void YamlReader::GetInRange(const std::string& key, int& out, int lo, int hi) {
  Get(key, out);
  CheckRange(key, out, lo, hi);
}
void YamlReader::GetPositiveUpTo(const std::string& key, double& out, double hi) {
  Get(key, out);
  CheckPositiveUpTo(key, out, hi);
}
void YamlReader::GetZeroOrInRange(const std::string& key, double& out, double lo, double hi) {
  Get(key, out);
  if (out == 0.0) return;
  if (out < 0.0) Fail(key, "must be >= 0 (got " + FormatNumber(out) + ")");
  if (out < lo) Fail(key, "must be 0 (off) or >= " + FormatNumber(lo) + " (got " + FormatNumber(out) + ")");
  if (out > hi) Fail(key, "must be <= " + FormatNumber(hi) + " (got " + FormatNumber(out) + ")");
}

void YamlReader::CheckRange(const std::string& key, double v, double lo, double hi) const {
  if (!(v >= lo)) Fail(key, "must be >= " + FormatNumber(lo) + " (got " + FormatNumber(v) + ")");
  if (!(v <= hi)) Fail(key, "must be <= " + FormatNumber(hi) + " (got " + FormatNumber(v) + ")");
}
void YamlReader::CheckPositiveUpTo(const std::string& key, double v, double hi) const {
  if (!(v > 0.0)) Fail(key, "must be > 0 (got " + FormatNumber(v) + ")");
  if (!(v <= hi)) Fail(key, "must be <= " + FormatNumber(hi) + " (got " + FormatNumber(v) + ")");
}

YamlReader YamlReader::Child(const std::string& key) {
  MarkRead(key, /*leaf=*/false);
  YAML::Node n;
  if (node_ && node_.IsMap() && node_[key]) n = node_[key];
  if (n && !n.IsNull() && !n.IsMap()) Fail(key, "expected a mapping of keys");
  return YamlReader(n, KeyPath(key), source_);
}

void YamlReader::ForEach(const std::string& key, std::size_t max_len,
                         const std::function<void(const YAML::Node&, const std::string&)>& fn) {
  MarkRead(key, /*leaf=*/true);
  if (!Has(key)) return;
  const YAML::Node n = node_[key];
  if (!n.IsSequence()) Fail(key, "expected a list");
  if (n.size() > max_len) {
    Fail(key, "at most " + std::to_string(max_len) + " entries (got " + std::to_string(n.size()) + ")");
  }
  for (std::size_t i = 0; i < n.size(); ++i) {
    fn(n[i], KeyPath(key) + "[" + std::to_string(i) + "]");
  }
}

YamlReader YamlReader::Element(const YAML::Node& node, const std::string& path) const {
  return YamlReader(node, path, source_);
}

void YamlReader::MarkRead(const std::string& key, bool leaf) {
  read_.insert(key);
  if (!leaf || !source_->keys_read) return;
  // Sequence indices become [], so every element of a list records one key path.
  static const std::regex kIndex(R"(\[[0-9]+\])");
  source_->keys_read->insert(std::regex_replace(KeyPath(key), kIndex, "[]"));
}

void YamlReader::Finish() const {
  if (!node_ || !node_.IsMap()) return;
  for (const auto& kv : node_) {
    const std::string& key = kv.first.Scalar();  // the constructor checked every key is a scalar
    if (!read_.count(key)) FailAt(kv.first, KeyPath(key), "unknown key");
  }
}

}  // namespace mapmesh
