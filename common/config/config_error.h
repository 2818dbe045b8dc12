#pragma once
// The one error type of scenario loading: its message is a single line that names the
// file, the line and the key ("scenarios/a.yaml:12: robots[1].sensor.max_range_m: ...").
// Keys and values quoted from the file may hold control characters (a quoted YAML key can
// hold a newline or a NUL): the message shows them escaped (\n, \x00), so it stays one line.

#include <stdexcept>
#include <string>

namespace mapmesh {

// `text` with every ASCII control character written as an escape: \n, \r, \t, or \xNN.
inline std::string EscapeControlCharacters(const std::string& text) {
  static constexpr char kHex[] = "0123456789abcdef";
  std::string out;
  out.reserve(text.size());
  for (const char ch : text) {
    const auto c = static_cast<unsigned char>(ch);
    if (c >= 0x20 && c != 0x7f) {
      out += ch;
    } else if (c == '\n') {
      out += "\\n";
    } else if (c == '\r') {
      out += "\\r";
    } else if (c == '\t') {
      out += "\\t";
    } else {
      out += "\\x";
      out += kHex[c >> 4];
      out += kHex[c & 0xf];
    }
  }
  return out;
}

class ConfigError : public std::runtime_error {
 public:
  explicit ConfigError(const std::string& message) : std::runtime_error(EscapeControlCharacters(message)) {}
};

}  // namespace mapmesh
