#pragma once
// Strict, typed access to one YAML mapping: every key read is remembered, and Finish()
// rejects the keys nobody asked for. Every error is a ConfigError naming file, line and key.

#include <yaml-cpp/yaml.h>

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "common/config/config_error.h"
#include "common/config/resolved.h"
#include "common/types/choice.h"

namespace mapmesh {

// Where a YAML tree came from, and which key paths were set on the command line.
struct YamlSource {
  std::string file;
  std::set<std::string> overridden;            // key paths given with --set
  std::set<std::string>* keys_read = nullptr;  // when set, collects the path of every value key read
                                               // (list indices as [], mappings only through their keys)
  ResolvedScenario* resolved = nullptr;        // when set, collects the value taken for each of them
};

// A number as error messages show it (1000000, 0.0524, 1e+300).
std::string FormatNumber(double v);

class YamlReader {
 public:
  // node must be a mapping (or null, treated as empty); path is its dotted key path. Its keys
  // must be plain scalars, each given once (yaml-cpp would keep the first of duplicates).
  YamlReader(YAML::Node node, std::string path, std::shared_ptr<const YamlSource> source);

  // Throws ConfigError for `key` (relative to this mapping) with `reason`.
  [[noreturn]] void Fail(const std::string& key, const std::string& reason) const;
  // Same, for a node anywhere below this mapping.
  [[noreturn]] void FailAt(const YAML::Node& node, const std::string& key_path, const std::string& reason) const;

  bool Has(const std::string& key) const;
  // The raw node for key (marks it as read); null node when absent.
  YAML::Node Raw(const std::string& key);

  // Reads an optional scalar into out; leaves out unchanged when absent.
  void Get(const std::string& key, double& out);
  void Get(const std::string& key, int& out);
  void Get(const std::string& key, std::uint64_t& out);
  void Get(const std::string& key, bool& out);
  void Get(const std::string& key, std::string& out);
  // Reads a fixed-length list of numbers ([x, y, theta] and the like).
  void GetVector(const std::string& key, std::vector<double>& out, std::size_t expected_len);

  // Reads a string that must be one of `choices`.
  void GetChoice(const std::string& key, std::string& out, const std::vector<std::string>& choices);
  // Reads an enum by its name in table (names listed in the table's order on error).
  template <typename E, std::size_t N>
  void GetChoice(const std::string& key, E& out, const ChoiceTable<E, N>& table) {
    std::string name(NameOf(table, out));
    std::vector<std::string> names;
    for (const ChoiceName<E>& c : table) names.emplace_back(c.name);
    GetChoice(key, name, names);
    out = *ParseChoice(table, name);
  }

  // Read an optional number and check its range, failing with the key's line: in [lo, hi];
  // in (0, hi]; 0 (off) or in [lo, hi]. A value out of range names the bound it breaks.
  void GetInRange(const std::string& key, double& out, double lo, double hi);
  void GetInRange(const std::string& key, int& out, int lo, int hi);
  void GetPositiveUpTo(const std::string& key, double& out, double hi);
  void GetZeroOrInRange(const std::string& key, double& out, double lo, double hi);

  // The same checks on a value already read (or computed from several keys).
  void CheckRange(const std::string& key, double v, double lo, double hi) const;
  void CheckPositiveUpTo(const std::string& key, double v, double hi) const;

  // A child mapping (an empty one when absent).
  YamlReader Child(const std::string& key);
  // A child sequence of at most max_len elements; each is passed to fn with its index path.
  void ForEach(const std::string& key, std::size_t max_len,
               const std::function<void(const YAML::Node&, const std::string&)>& fn);
  // Reader for an element of a sequence obtained with ForEach.
  YamlReader Element(const YAML::Node& node, const std::string& path) const;

  // Rejects keys that were never read. Call once all known keys have been read.
  void Finish() const;

  int LineOf(const YAML::Node& node) const;
  std::string KeyPath(const std::string& key) const { return path_.empty() ? key : path_ + "." + key; }

 private:
  template <typename T>
  void GetScalar(const std::string& key, T& out, const char* type_name);
  // Remembers key as read (for Finish) and, for a value (leaf), in source().keys_read.
  void MarkRead(const std::string& key, bool leaf);
  // Records the value taken for key in source().resolved.
  void Resolve(const std::string& key, ResolvedValue::Kind kind, std::string text) const;
  void ResolveList(const std::string& key, const std::vector<double>& v) const;
  // Throws ConfigError at node's line in the file, even below a key given with --set.
  [[noreturn]] void FailInFile(const YAML::Node& node, const std::string& key_path, const std::string& reason) const;

  YAML::Node node_;
  std::string path_;
  std::shared_ptr<const YamlSource> source_;
  std::set<std::string> read_;
};

}  // namespace mapmesh
