#pragma once
// The one summary record of a run at an observed step. The solver side fills it; the CSV
// history, the terminal and the live DDS summary all read it. for_each_field is the only
// place that lists the fields, with their units.
#include <cmath>
#include <cstddef>
#include <limits>
#include <type_traits>

namespace peridot {

struct RunRecord {
  std::size_t step = 0;
  double time = 0;             // simulated time [s]
  double kinetic_energy = 0;   // [J] (2D: J/m)
  double strain_energy = 0;    // [J]
  double external_work = 0;    // work of loads and constraints [J]
  std::size_t broken_bonds = 0;
  double damage_fraction = 0;  // volume-weighted mean damage
  long fragments = -1;         // -1: not counted
  double tip_x = std::numeric_limits<double>::quiet_NaN();  // crack tip [m]; NaN: none
  double tip_y = std::numeric_limits<double>::quiet_NaN();
  double tip_speed = std::numeric_limits<double>::quiet_NaN();  // [m/s]
  double wall_time = 0;        // wall-clock seconds since the run started
  // Implicit solvers, summed over the steps since the previous row; -1 for explicit runs.
  long linear_iterations = -1; // Krylov iterations
  long sub_iterations = -1;    // re-solves after bonds broke
};

// Calls f(name, unit, member) for every field in a fixed order; unit is "" for counts.
template <class Record, class F>
  requires std::is_same_v<std::remove_const_t<Record>, RunRecord>
constexpr void for_each_field(Record& r, F&& f) {
  f("step", "", r.step);
  f("time", "s", r.time);
  f("kinetic", "J", r.kinetic_energy);
  f("strain", "J", r.strain_energy);
  f("external_work", "J", r.external_work);
  f("broken_bonds", "", r.broken_bonds);
  f("damage_fraction", "", r.damage_fraction);
  f("fragments", "", r.fragments);
  f("tip_x", "m", r.tip_x);
  f("tip_y", "m", r.tip_y);
  f("tip_speed", "m/s", r.tip_speed);
  f("wall_time", "s", r.wall_time);
  f("linear_iterations", "", r.linear_iterations);
  f("sub_iterations", "", r.sub_iterations);
}

}  // namespace peridot
