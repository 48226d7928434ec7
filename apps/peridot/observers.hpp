#pragma once
#include <cstddef>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>
#include <peridot/run_record.hpp>

#include "commands.hpp"
import peridot.problem;
import peridot.analysis;
import peridot.live;

// The live publisher's options from the command line: run id (default <name>-<pid>), domain, partition.
peridot::LiveOptions live_options(const RunArgs& args, const std::string& name);

// Everything a run reports while it goes: VTU/PVD, CSV history, PNG snapshots, live DDS
// state, fragment counts and crack-tip tracking, each on its own cadence (deck `output`).
// Called once per step; does work only on steps where some observer is due.
class Observers {
 public:
  // damage_of: a model's own damage field (RNP: max |S| / S_c); empty: broken-bond damage.
  using DamageFunction = std::function<void(const peridot::VectorField& u, std::vector<double>& phi)>;
  // stress_of: the peridynamic stress tau of the run's model at u (peridot::stress_field); empty
  // when the model has no pair forces, and then no output may ask for the stress.
  using StressFunction = std::function<void(const peridot::VectorField& u, peridot::StressField& tau)>;
  // resume_step > 0: a run restarted from a checkpoint at that step. The CSV history keeps its
  // rows before the step and the .pvd its earlier files; crack-tip and fragment tracking start
  // afresh from the restart.
  Observers(const peridot::Problem& problem, const peridot::Body& body, const std::filesystem::path& dir, peridot::LiveOptions live,
            DamageFunction damage_of = {}, StressFunction stress_of = {}, std::size_t resume_step = 0);
  // The deck key that asks for the stress ("output.vtu.stress = true", a stress output.png.field),
  // or "" when no output needs it.
  static std::string stress_request(const peridot::OutputSpec& o);
  // Whether any observer of `o` reports at this step.
  static bool due_at(const peridot::OutputSpec& o, std::size_t step, bool last);
  // Whether an output of cadence `every` (0: off) reports at this step.
  static bool due(std::size_t every, std::size_t step, bool last) { return every > 0 && (step % every == 0 || last); }
  void observe(const peridot::State& state, double external_work, std::size_t broken, const std::function<double()>& strain, bool last,
               double wall);
  void finish(bool ok, const std::string& message);
  // An implicit solver's work in one step; rows report the sums since the previous row.
  void add_solver_work(long iterations, long sub_iterations) {
    iterations_ += iterations;
    sub_iterations_ += sub_iterations;
    implicit_ = true;
  }
  const peridot::RunRecord& last_row() const { return row_; }
  void print_summary() const;
  // The closing lines of a run: steps, wall time, broken bonds, the observers' summaries and
  // the files written. `extra` is printed after the first line when not empty.
  void print_done(const peridot::State& state, double wall, std::size_t broken, const std::string& extra = {}) const;
  std::vector<std::string> outputs() const;

 private:

  const peridot::Problem& p_;
  DamageFunction damage_of_;
  StressFunction stress_of_;
  const peridot::Body& body_;
  std::filesystem::path dir_;
  peridot::PvdSeries vtu_;
  std::unique_ptr<peridot::HistoryCsv> csv_;
  std::optional<peridot::CrackTipTracker> tips_;
  std::unique_ptr<peridot::LivePublisher> live_;
  std::optional<peridot::FragmentReport> fragments_;
  std::vector<double> phi_, deformed_[3], von_mises_;
  peridot::StressField stress_;
  peridot::RunRecord row_;
  std::size_t pngs_ = 0;
  std::size_t published_ = 0;
  double publish_seconds_ = 0;  // solver-thread time spent in LivePublisher calls
  std::filesystem::path last_png_;
  long iterations_ = 0, sub_iterations_ = 0;
  bool implicit_ = false;
};
