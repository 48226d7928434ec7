#pragma once
// The one summary record of a run at an observed step. The solver side fills it; the CSV
// history, the terminal and the live DDS summary all read it. for_each_field is the only
// place that lists the fields, with their units.
// It includes no standard header: module units include it in their global fragment, where a
// standard header would cost clang seconds of merging with the one peridot.std holds.

namespace peridot {

namespace record_detail {
using size = decltype(sizeof 0);  // std::size_t
template <class T>
inline constexpr bool is_run_record = false;
}  // namespace record_detail

struct RunRecord {
  record_detail::size step = 0;
  double time = 0;             // simulated time [s]
  double kinetic_energy = 0;   // [J] (2D: J/m)
  double strain_energy = 0;    // [J]
  double external_work = 0;    // work of loads and constraints [J]
  record_detail::size broken_bonds = 0;
  double damage_fraction = 0;  // volume-weighted mean damage
  long fragments = -1;         // -1: not counted
  double tip_x = __builtin_nan("");  // crack tip [m]; NaN: none
  double tip_y = __builtin_nan("");
  double tip_speed = __builtin_nan("");  // [m/s]
  double wall_time = 0;        // wall-clock seconds since the run started
  // Implicit solvers, summed over the steps since the previous row; -1 for explicit runs.
  long linear_iterations = -1; // Krylov iterations
  long sub_iterations = -1;    // re-solves after bonds broke
  // The 3D crack front (output.crack_front), as its own CSV has it; NaN and -1: not tracked.
  double front_length = __builtin_nan("");        // the polyline through the slices' front points [m]
  double front_mean_advance = __builtin_nan("");  // from the deck's origin, along its direction [m]
  double front_max_advance = __builtin_nan("");   // [m]
  double front_max_speed = __builtin_nan("");     // the fastest slice at this sample [m/s]
  long front_branched_slices = -1;
};

// Calls f(name, unit, member) for every field in a fixed order; unit is "" for counts.
namespace record_detail {
template <>
inline constexpr bool is_run_record<RunRecord> = true;
template <>
inline constexpr bool is_run_record<const RunRecord> = true;
}  // namespace record_detail

template <class Record, class F>
  requires record_detail::is_run_record<Record>
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
  f("front_length", "m", r.front_length);
  f("front_mean_advance", "m", r.front_mean_advance);
  f("front_max_advance", "m", r.front_max_advance);
  f("front_max_speed", "m/s", r.front_max_speed);
  f("front_branched_slices", "", r.front_branched_slices);
}

}  // namespace peridot
