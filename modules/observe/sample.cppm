module;
#include <peridot/run_record.hpp>
export module peridot.observe:sample;
import peridot.std;
import peridot.problem;

export namespace peridot {

// What an observer sees on a step it is due: the body (reference positions, volumes, bonds),
// the state (u, v, f, time, step) and the history row of that step (energies, broken bonds,
// damage fraction, fragments, crack tip). Plain data: valid during the call only.
struct Sample {
  const Body& body;
  const State& state;
  const RunRecord& record;
  bool last;  // the run's final step (also when it stops early)
};

// How a run ended, as observers are told once at its end.
struct RunEnd {
  bool ok = true;             // finished every step
  bool interrupted = false;   // a stop was requested (signal or request_stop())
  std::string message;        // why it failed or stopped; empty when ok
  std::size_t steps = 0;      // the last step taken
  double wall_seconds = 0;
};

// A user-defined observer: any small type with observe(const Sample&), and optionally
// finish(const RunEnd&). Simulation::add_observer takes it with a cadence in steps.
template <class T>
concept Observer = requires(T& t, const Sample& s) { t.observe(s); };

// An observer of any type, held by the run. Called only on steps where it is due, so the cost
// of the indirection is per report, not per bond.
class AnyObserver {
 public:
  template <Observer T>
  AnyObserver(T observer, std::size_t every = 1) : every_(every) {
    auto held = std::make_shared<T>(std::move(observer));
    observe_ = [held](const Sample& s) { held->observe(s); };
    if constexpr (requires(const RunEnd& e) { held->finish(e); }) finish_ = [held](const RunEnd& e) { held->finish(e); };
  }
  bool due(std::size_t step, bool last) const { return every_ > 0 && (step % every_ == 0 || last); }
  void observe(const Sample& s) const { observe_(s); }
  void finish(const RunEnd& e) const {
    if (finish_) finish_(e);
  }

 private:
  std::size_t every_;
  std::function<void(const Sample&)> observe_;
  std::function<void(const RunEnd&)> finish_;
};

}  // namespace peridot
