#pragma once
// Whitespace-separated numeric tables, as the MRCLAM and Victoria Park files are: tabs and
// spaces mixed, trailing spaces, '#' header lines. Errors name the file and the line.

#include <stdexcept>
#include <string>
#include <vector>

namespace mapmesh {

// A dataset that cannot be read: the message is one line naming the file (and line).
class DatasetError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct TableRow {
  int line = 0;           // 1-based line in the file
  std::vector<double> v;  // exactly the requested number of columns
};

// Reads every data row of path; each must hold exactly `columns` numbers.
// Throws DatasetError "path: cannot open" or "path:LINE: expected N numbers".
std::vector<TableRow> ReadTable(const std::string& path, std::size_t columns);

// Parses one line into numbers; false if it is not exactly `columns` numbers.
bool ParseRow(const std::string& line, std::size_t columns, std::vector<double>& out);

}  // namespace mapmesh
