#pragma once
// The resolved scenario: every value key the loader read, with the value it took (given in the
// file, overridden with --set, or the default). Plain data, no YAML library.

#include <map>
#include <string>

namespace mapmesh {

// One value: what the loader took for a key.
struct ResolvedValue {
  enum class Kind { kNumber, kBool, kString, kYaml };
  Kind kind = Kind::kString;
  std::string text;  // a number as the shortest text that reads back to it; true/false; the string;
                     // kYaml: the node as given, in YAML flow style (lists read whole)
  bool operator==(const ResolvedValue&) const = default;
};

// By key path (list elements as key[i]), in path order.
using ResolvedScenario = std::map<std::string, ResolvedValue>;

}  // namespace mapmesh
