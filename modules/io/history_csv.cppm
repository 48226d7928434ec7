module;
#include <cmath>
#include <cstdio>
#include <filesystem>
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
  explicit HistoryCsv(const std::filesystem::path& file);
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

HistoryCsv::HistoryCsv(const std::filesystem::path& file) : f_(std::fopen(file.c_str(), "w")) {
  if (!f_) throw std::runtime_error(fmt::format("cannot write {}", file.string()));
  fmt::print(f_, "{}\n", header());
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
