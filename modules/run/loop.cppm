module;
#include <peridot/run_record.hpp>
export module peridot.run:loop;
import peridot.std;
import peridot.problem;
import peridot.observe;
import peridot.live;
import :stop;

export namespace peridot {

// How a run is driven; every field has a default, so RunOptions{} runs a deck as written.
struct RunOptions {
  std::optional<std::filesystem::path> out_dir;  // overrides output.directory
  LiveOptions live;                              // DDS: run id (empty: <name>-<pid>), domain, partition
  std::optional<std::filesystem::path> restart;  // explicit runs: continue from this checkpoint
  bool progress = false;                         // a progress line on stderr, when it is a terminal
  std::size_t max_steps = 0;                     // end after this many steps (benchmarks, previews); 0: the deck's end
  // Where the run's report goes, line by line (set-up, checkpoints, per-step lines of implicit
  // solvers, the closing summary); empty: nowhere. On N ranks only rank 0 reports.
  std::function<void(const std::string&)> print;
  std::function<void(const std::string&)> warn;  // warnings (a dt above the stable estimate, unread PETSc options)
};

// How a run ended without an error (errors are exceptions: DeckError for input, before any
// file; std::runtime_error once the run has started).
struct RunOutcome {
  bool interrupted = false;  // a stop was requested; the last step's outputs were written
  int signal = 0;            // the signal that asked for the stop, 0 if none
  std::size_t steps = 0;     // the step the run ended at
  std::size_t broken = 0;    // broken bonds at the end (quasi-static: softening bonds)
  double wall_seconds = 0;
  RunRecord last;            // the history row of the last report (rank 0)
  // The process exit status a command-line tool should end with: 0, or 128 + the signal.
  int exit_status() const { return interrupted ? (signal > 0 ? 128 + signal : 1) : 0; }
};

// What a stepper hands the observers on a step where one is due.
struct Report {
  const State* state = nullptr;  // null on a rank that does not report (N ranks: all but rank 0)
  double external_work = 0;
  std::size_t broken = 0;        // broken bonds since t = 0 (or softening bonds, quasi-static)
  std::function<double()> strain;
  std::optional<Observers::Totals> totals;  // reduced over N ranks; absent: the observers sum the state
};

// One flavour of run, advanced one unit at a time: an explicit step, a Newmark step, a
// converged load increment, a static solve. The one loop (drive) does everything else.
template <class S>
concept Stepper = requires(S& s, const S& c, bool last) {
  { c.done() } -> std::convertible_to<bool>;
  s.advance();
  { c.step() } -> std::convertible_to<std::size_t>;
  { c.steps() } -> std::convertible_to<std::size_t>;  // how many to the end
  { c.time() } -> std::convertible_to<double>;
  { c.broken() } -> std::convertible_to<std::size_t>;
  // The state for observers, on a step where something is due (N ranks gather here).
  { s.report(last) } -> std::same_as<Report>;
};

// Optional offers a stepper makes, found by the loop at compile time:
//   s.checkpoint(file)          writes its restart state (explicit runs)
//   s.solver_work()             {iterations, sub-iterations} of the last advance (implicit)
//   s.step_line()               a line per step for the report (quasi-static)
//   s.agree(bool)               N ranks: the value any rank holds (a stop request)
//   s.summary()                 closing lines before the observers'
//   s.abscissa()                what the record's "time" is, when not time [s] (load factor, solve count)
//   s.open_ended()              steps() is a bound, not a plan (fracture re-solves): no ETA
//   s.writes_vtu(), writes_png() outputs the stepper writes itself (N-rank pieces, static results)
//   s.final_outputs(dir)        its own files after the last step
//   s.open_outputs(dir)         opens files the stepper writes on every rank (VTU pieces)
//   s.observers(dir)            observers of its own, beside the deck's (the load-step CSV)
//   s.damage_function()         the model's own damage (RNP), else the bonds' broken fraction
//   s.stress_function()         the stress tensor, for models with pair forces
//   s.part()                    N ranks: this rank's part, for part observers (PartView); one
//                               process needs none (its part is s.body() and the report's state)

// This rank's part as a part observer reads it (PartSample).
struct PartView {
  const Body* body = nullptr;
  const State* state = nullptr;
  std::span<const std::int64_t> owned, ids;
  std::uint64_t points = 0;
  int rank = 0, ranks = 1;
};

// What the loop needs of the run around the stepper.
struct Loop {
  const OutputSpec& output;
  Observers* observers = nullptr;                 // null on ranks that do not report
  const std::vector<AnyObserver>* users = nullptr;  // for cadences, on every rank
  const std::vector<AnyPartObserver>* parts = nullptr;  // every rank observes
  PartReductions reductions;                            // over the ranks (one process: the value)
  std::filesystem::path checkpoint_file;
  bool progress = false;
  std::size_t max_steps = 0;  // 0: until the stepper is done
  std::function<void(const std::string&)> print;
};

namespace detail {
inline bool due(std::size_t every, std::size_t n, bool last) { return every > 0 && (n % every == 0 || last); }
}  // namespace detail

// The one run loop: observe the start, then advance, observe on cadence, checkpoint, show
// progress, until the stepper is done or a stop is requested; then finish or fail.
template <Stepper S>
RunOutcome drive(S& s, const Loop& loop) {
  const auto& o = loop.output;
  const auto t0 = std::chrono::steady_clock::now();
  const auto wall = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(); };
  const auto say = [&](const std::string& line) {
    if (loop.print && loop.observers) loop.print(line);
  };
  const std::size_t end = loop.max_steps ? std::min(s.steps(), s.step() + loop.max_steps) : s.steps();
  const auto finished = [&] { return s.done() || (loop.max_steps && s.step() >= end); };
  bool open_ended = false;
  if constexpr (requires { s.open_ended(); }) open_ended = s.open_ended();
  std::string abscissa;
  if constexpr (requires { s.abscissa(); }) abscissa = s.abscissa();
  Progress progress(open_ended && !loop.max_steps ? 0 : end, loop.progress && loop.observers, s.step(), abscissa);
  RunOutcome out;
  const auto parts_due = [&](std::size_t n, bool last) {
    return loop.parts && std::ranges::any_of(*loop.parts, [&](const AnyPartObserver& u) { return u.due(n, last); });
  };
  // The same answer on every rank: built from the deck and the user observers, which every rank has.
  const auto observers_due = [&](std::size_t n, bool last) {
    if (Observers::due_at(o, n, last)) return true;
    if (loop.users)
      for (const auto& u : *loop.users)
        if (u.due(n, last)) return true;
    return parts_due(n, last);
  };
  // One process: the part is the whole body, every point owned, its id its index.
  std::vector<std::int64_t> every_point;
  const auto observe_parts = [&](const Report& r, bool last) {
    const std::size_t n = s.step();
    if (!parts_due(n, last)) return;
    PartView v;
    if constexpr (requires { s.part(); })
      if (const std::optional<PartView> mine = s.part()) v = *mine;
    if (!v.body) {
      if (!r.state) throw std::logic_error("drive: a stepper on N ranks offers no part for part observers");
      const Body& b = s.body();
      if (every_point.size() != b.size()) {
        every_point.resize(b.size());
        std::iota(every_point.begin(), every_point.end(), std::int64_t(0));
      }
      v = {&b, r.state, every_point, every_point, b.size()};
    }
    const PartSample sample{*v.body, *v.state, v.owned, v.ids, v.points, loop.observers ? &loop.observers->last_row() : nullptr, last,
                            v.rank, v.ranks, loop.reductions};
    for (const auto& u : *loop.parts)
      if (u.due(n, last)) u.observe(sample);
  };
  const auto finish_parts = [&](const RunEnd& end) {
    if (loop.parts)
      for (const auto& u : *loop.parts) u.finish(end);
  };
  const auto report = [&](bool last, bool initial) {
    const std::size_t n = s.step();
    bool checkpoint = false;
    if constexpr (requires { s.checkpoint(loop.checkpoint_file); })
      checkpoint = !initial && detail::due(o.checkpoint_every, n, last);
    const bool observe = observers_due(n, last);
    if (!observe && !checkpoint) return;
    const Report r = s.report(last);
    if (r.state && observe && loop.observers)
      loop.observers->observe(*r.state, r.external_work, r.broken, r.strain, last, wall(), r.totals ? &*r.totals : nullptr);
    // Every rank, after rank 0's history row is made (part observers read it there).
    if (observe) observe_parts(r, last);
    // Every rank: on N ranks each may write its part (the report's state is rank 0's only).
    if constexpr (requires { s.checkpoint(loop.checkpoint_file); })
      if (checkpoint) {
        s.checkpoint(loop.checkpoint_file);
        if (!r.state) return;
        progress.clear();
        say(fmt::format("  checkpoint: step {}, t = {:.4e} s -> {}", n, r.state->time, loop.checkpoint_file.string()));
      }
  };
  const auto stop_now = [&] {
    bool stop = stop_requested();
    if constexpr (requires { s.agree(stop); }) stop = s.agree(stop);
    return stop;
  };
  try {
    report(finished(), true);
    while (!finished()) {
      s.advance();
      if constexpr (requires { s.solver_work(); })
        if (loop.observers) {
          const auto [iterations, sub_iterations] = s.solver_work();
          loop.observers->add_solver_work(iterations, sub_iterations);
        }
      if constexpr (requires { s.step_line(); }) {
        progress.clear();
        say(s.step_line());
      }
      // A stop ends the run at this step: its outputs are written as the last ones.
      out.interrupted = !finished() && stop_now();
      report(finished() || out.interrupted, false);
      progress.update(s.step(), s.time(), s.broken());
      if (out.interrupted) break;
    }
  } catch (const std::exception& e) {
    progress.finish();
    const RunEnd failed{.ok = false, .message = e.what(), .steps = s.step(), .wall_seconds = wall()};
    if (loop.observers) loop.observers->finish(failed);
    finish_parts(failed);
    throw;
  }
  progress.finish();
  out.steps = s.step();
  out.broken = s.broken();
  out.wall_seconds = wall();
  out.signal = out.interrupted ? stop_signal() : 0;
  const RunEnd ended{.ok = !out.interrupted, .interrupted = out.interrupted, .message = out.interrupted ? "interrupted" : "", .steps = out.steps,
                   .wall_seconds = out.wall_seconds};
  if (loop.observers) {
    out.last = loop.observers->last_row();
    loop.observers->finish(ended);
  }
  finish_parts(ended);
  if (loop.print && loop.observers) {
    if (out.interrupted)
      loop.print(fmt::format("  interrupted{}: stopped after step {} of {}, t = {:.4e} s", out.signal ? fmt::format(" by signal {}", out.signal) : "",
                             out.steps, s.steps(), s.time()));
    // The damage fraction is the last observed row's; a run that observed none does not make one up.
    loop.print(fmt::format("  done: {} steps in {:.2f} s ({:.3e} s/step), {} bonds broken{}", out.steps, out.wall_seconds,
                           out.wall_seconds / double(std::max<std::size_t>(out.steps, 1)), s.broken(),
                           loop.observers->observed() ? fmt::format(", damage fraction {:.4f}", out.last.damage_fraction) : std::string()));
    if constexpr (requires { s.summary(); })
      for (const auto& line : s.summary()) loop.print(line);
    for (const auto& line : loop.observers->summary()) loop.print(line);
  }
  return out;
}

}  // namespace peridot
