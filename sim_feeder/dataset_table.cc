#include "sim_feeder/dataset_table.h"

#include <cmath>
#include <cstdlib>
#include <fstream>

namespace mapmesh {

bool ParseRow(const std::string& line, std::size_t columns, std::vector<double>& out) {
  out.clear();
  const char* p = line.c_str();
  while (true) {
    while (*p == ' ' || *p == '\t' || *p == '\r') ++p;
    if (*p == '\0') break;
    char* end = nullptr;
    const double v = std::strtod(p, &end);
    if (end == p || (*end != '\0' && *end != ' ' && *end != '\t' && *end != '\r')) return false;
    if (!std::isfinite(v)) return false;
    out.push_back(v);
    p = end;
  }
  return out.size() == columns;
}

std::vector<TableRow> ReadTable(const std::string& path, std::size_t columns) {
  std::ifstream in(path);
  if (!in) throw DatasetError(path + ": cannot open");
  std::vector<TableRow> rows;
  std::string line;
  int lineno = 0;
  std::vector<double> v;
  while (std::getline(in, line)) {
    ++lineno;
    const auto first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    if (!ParseRow(line, columns, v)) {
      throw DatasetError(path + ":" + std::to_string(lineno) + ": expected " + std::to_string(columns) +
                         " numbers, got '" + line.substr(0, 60) + "'");
    }
    rows.push_back({lineno, v});
  }
  return rows;
}

}  // namespace mapmesh
