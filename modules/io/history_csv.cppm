module;
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <fmt/core.h>
export module peridot.io:history_csv;

export namespace peridot {

// Global quantities at one output step.
struct HistoryRow {
  std::size_t step = 0;
  double time = 0;             // [s]
  double kinetic = 0;          // [J] (2D: J/m)
  double strain = 0;           // [J]
  double external_work = 0;    // [J]
  std::size_t broken_bonds = 0;
  double damage_fraction = 0;  // volume-weighted mean damage
  long fragments = -1;         // -1: not counted
  double tip_x = NAN, tip_y = NAN, tip_speed = NAN;  // crack tip [m], [m/s]; NaN: none
};

// CSV history, one row per output step, flushed per row so a crash keeps whole rows only.
class HistoryCsv {
 public:
  explicit HistoryCsv(const std::filesystem::path& file);
  ~HistoryCsv();
  HistoryCsv(const HistoryCsv&) = delete;
  HistoryCsv& operator=(const HistoryCsv&) = delete;
  void append(const HistoryRow& r);
  static constexpr const char* header =
      "step,time_s,kinetic_J,strain_J,external_work_J,broken_bonds,damage_fraction,fragments,tip_x_m,tip_y_m,tip_speed_m_s";

 private:
  std::FILE* f_ = nullptr;
};

}  // namespace peridot

namespace peridot {

HistoryCsv::HistoryCsv(const std::filesystem::path& file) : f_(std::fopen(file.c_str(), "w")) {
  if (!f_) throw std::runtime_error(fmt::format("cannot write {}", file.string()));
  fmt::print(f_, "{}\n", header);
  std::fflush(f_);
}

HistoryCsv::~HistoryCsv() {
  if (f_) std::fclose(f_);
}

void HistoryCsv::append(const HistoryRow& r) {
  fmt::print(f_, "{},{:.9e},{:.9e},{:.9e},{:.9e},{},{:.9e},{},{:.9e},{:.9e},{:.9e}\n", r.step, r.time, r.kinetic, r.strain,
             r.external_work, r.broken_bonds, r.damage_fraction, r.fragments, r.tip_x, r.tip_y, r.tip_speed);
  std::fflush(f_);
}

}  // namespace peridot
