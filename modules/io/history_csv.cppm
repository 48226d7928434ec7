module;
#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <fmt/core.h>
#include <peridot/run_record.hpp>
export module peridot.io:history_csv;

export namespace peridot {


// CSV history, one row per output step, flushed per row so a crash keeps whole rows only.
// Columns follow for_each_field: name_unit (e.g. time_s, tip_speed_m_s).
class HistoryCsv {
 public:
  // keep_before_step > 0 continues a restarted run's history: whole rows of an existing file
  // with step < keep_before_step are kept (rewritten atomically), later ones dropped; a file
  // with another header is started afresh.
  explicit HistoryCsv(const std::filesystem::path& file, std::size_t keep_before_step = 0);
  ~HistoryCsv();
  HistoryCsv(const HistoryCsv&) = delete;
  HistoryCsv& operator=(const HistoryCsv&) = delete;
  void append(const RunRecord& r);
  static std::string header();

 private:
  std::FILE* f_ = nullptr;
};

}  // namespace peridot

namespace peridot {

std::string HistoryCsv::header() {
  std::string h;
  const RunRecord r{};
  for_each_field(r, [&](const char* name, std::string unit, const auto&) {
    for (auto& c : unit) c = c == '/' ? '_' : c;
    h += fmt::format("{}{}{}{}", h.empty() ? "" : ",", name, unit.empty() ? "" : "_", unit);
  });
  return h;
}

namespace {

// The rows of an existing history before step `before`; a partial row (a run killed while
// writing it) ends them.
std::string rows_before(const std::filesystem::path& file, const std::string& header, std::size_t before) {
  std::ifstream in(file);
  std::string line, rows;
  if (!in || !std::getline(in, line) || line != header) return rows;
  const auto columns = std::count(header.begin(), header.end(), ',');
  while (std::getline(in, line) && !in.eof() && std::count(line.begin(), line.end(), ',') == columns) {
    std::size_t step = 0;
    const auto [end, ec] = std::from_chars(line.data(), line.data() + line.size(), step);
    if (ec != std::errc() || *end != ',' || step >= before) break;
    rows += line + '\n';
  }
  return rows;
}

}  // namespace

HistoryCsv::HistoryCsv(const std::filesystem::path& file, std::size_t keep_before_step) {
  if (keep_before_step > 0) {
    const auto tmp = file.string() + ".tmp";
    {
      std::ofstream out(tmp, std::ios::binary);
      out << header() << '\n' << rows_before(file, header(), keep_before_step);
      if (!out) throw std::runtime_error(fmt::format("cannot write {}", tmp));
    }
    std::filesystem::rename(tmp, file);
    f_ = std::fopen(file.c_str(), "a");
  } else {
    f_ = std::fopen(file.c_str(), "w");
    if (f_) fmt::print(f_, "{}\n", header());
  }
  if (!f_) throw std::runtime_error(fmt::format("cannot write {}", file.string()));
  std::fflush(f_);
}

HistoryCsv::~HistoryCsv() {
  if (f_) std::fclose(f_);
}

void HistoryCsv::append(const RunRecord& r) {
  bool first = true;
  for_each_field(r, [&](const char*, const char*, const auto& v) {
    if (!first) std::fputc(',', f_);
    first = false;
    if constexpr (std::is_floating_point_v<std::remove_cvref_t<decltype(v)>>) fmt::print(f_, "{:.9e}", v);
    else fmt::print(f_, "{}", v);
  });
  std::fputc('\n', f_);
  std::fflush(f_);
}

}  // namespace peridot
