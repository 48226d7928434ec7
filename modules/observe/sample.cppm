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

// What a part observer sees on its cadence, on every rank at once. A run on N MPI ranks cuts the
// body into parts (one process holds one part: the whole body); a part observer reads the
// points this rank holds and their state, which of them it owns, and each one's index in the
// whole body. No rank gathers the body for it, so it costs what it computes whatever N is,
// where a Sample observer on N ranks makes rank 0 gather every point's fields (about 160 B per
// point). sum, max and min reduce over the ranks and return the same value on every rank; sum
// adds exactly (ExactSum), so a total does not depend on the rank count. They are collective:
// every rank's observer calls the same reductions in the same order.
struct PartReductions {  // one process: the value itself
  std::function<void(ExactSum&)> sum = [](ExactSum&) {};
  std::function<double(double)> max = [](double x) { return x; };
  std::function<double(double)> min = [](double x) { return x; };
};
struct PartSample {
  const Body& body;                     // this rank's points, owned and ghosts, by ascending id (reference positions, volumes, bonds)
  const State& state;                   // their u, v, f, the run's time and step (a ghost's u is its owner's; read v and f on owned points)
  std::span<const std::int64_t> owned;  // local indices of the points this rank owns, ascending
  std::span<const std::int64_t> ids;    // every local point's index in the whole body
  std::uint64_t points;                 // in the whole body
  const RunRecord* record;              // the step's history row on rank 0; null on the other ranks
  bool last;                            // the run's final step (also when it stops early)
  int rank = 0, ranks = 1;
  const PartReductions& reductions;

  double sum(ExactSum local) const {
    reductions.sum(local);
    return local.value();
  }
  double max(double local) const { return reductions.max(local); }
  double min(double local) const { return reductions.min(local); }
};

// A part observer: any small type with observe(const PartSample&), and optionally
// finish(const RunEnd&), which every rank calls. Simulation::add_observer takes it as it takes
// an Observer; a type that is both is taken as a part observer.
template <class T>
concept PartObserver = requires(T& t, const PartSample& s) { t.observe(s); };

// An observer of any type, held by the run. Called only on steps where it is due, so the cost
// of the indirection is per report, not per bond.
template <class S>
class AnyObserverOf {
 public:
  template <class T>
    requires requires(T& t, const S& s) { t.observe(s); }
  AnyObserverOf(T observer, std::size_t every = 1) : every_(every) {
    auto held = std::make_shared<T>(std::move(observer));
    observe_ = [held](const S& s) { held->observe(s); };
    if constexpr (requires(const RunEnd& e) { held->finish(e); }) finish_ = [held](const RunEnd& e) { held->finish(e); };
  }
  bool due(std::size_t step, bool last) const { return every_ > 0 && (step % every_ == 0 || last); }
  std::size_t every() const { return every_; }
  void observe(const S& s) const { observe_(s); }
  void finish(const RunEnd& e) const {
    if (finish_) finish_(e);
  }

 private:
  std::size_t every_;
  std::function<void(const S&)> observe_;
  std::function<void(const RunEnd&)> finish_;
};
using AnyObserver = AnyObserverOf<Sample>;
using AnyPartObserver = AnyObserverOf<PartSample>;

}  // namespace peridot
