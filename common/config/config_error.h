#pragma once
// The one error type of scenario loading: its message is a single line that names the
// file, the line and the key ("scenarios/a.yaml:12: robots[1].sensor.max_range_m: ...").

#include <stdexcept>
#include <string>

namespace mapmesh {

class ConfigError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace mapmesh
