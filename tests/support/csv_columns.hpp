#pragma once
// A CSV file with a header row, read as columns of numbers by header name (cells that are not
// numbers read as NaN).
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

namespace csv_columns {

inline std::map<std::string, std::vector<double>> read(const std::filesystem::path& file) {
  std::ifstream in(file);
  std::string header;
  std::getline(in, header);
  std::vector<std::string> names;
  std::stringstream hs(header);
  for (std::string c; std::getline(hs, c, ',');) names.push_back(c);
  std::map<std::string, std::vector<double>> out;
  for (const auto& n : names) out[n];
  for (std::string line; std::getline(in, line);) {
    std::stringstream ls(line);
    std::string cell;
    for (std::size_t k = 0; k < names.size(); ++k) {
      if (!std::getline(ls, cell, ',')) cell.clear();
      char* end = nullptr;
      const double v = std::strtod(cell.c_str(), &end);
      out[names[k]].push_back(end != cell.c_str() ? v : NAN);
    }
  }
  return out;
}

}  // namespace csv_columns
