module;
#include <stdio.h>  // stderr
#include <unistd.h>

export module peridot.observe:progress;
import peridot.std;

export namespace peridot {

// One self-overwriting progress line on a terminal, throttled; silent when stderr is not a tty.
class Progress {
 public:
  // first_step: where a restarted run begins (the ETA counts steps from there). total_steps 0:
  // open-ended (a fracture run of re-solves), shown without a total or ETA. abscissa: what the
  // run's "time" is when it is not time in seconds (a load factor, a solve count).
  Progress(std::size_t total_steps, bool enabled, std::size_t first_step = 0, std::string abscissa = {})
      : total_(total_steps), first_(first_step), enabled_(enabled && isatty(STDERR_FILENO)), abscissa_(std::move(abscissa)),
        start_(std::chrono::steady_clock::now()), last_(start_) {}

  void update(std::size_t step, double time, std::size_t broken) {
    if (!enabled_) return;
    const auto now = std::chrono::steady_clock::now();
    if (now - last_ < std::chrono::milliseconds(250) && step != total_) return;
    last_ = now;
    const double elapsed = std::chrono::duration<double>(now - start_).count();
    // Quasi-static runs may take more increments than planned (cut steps): no ETA past the plan.
    const double eta = step > first_ && step < total_ ? elapsed * double(total_ - step) / double(step - first_) : 0.0;
    const auto when = abscissa_.empty() ? fmt::format("t = {:.4e} s", time) : fmt::format("{} {:g}", abscissa_, time);
    if (total_ == 0) fmt::print(stderr, "\r  step {:>8}  {}  broken bonds {:>9}   ", step, when, broken);
    else fmt::print(stderr, "\r  step {:>8}/{}  {}  ETA {:>6.1f} s  broken bonds {:>9}   ", step, total_, when, eta, broken);
    std::fflush(stderr);
  }
  // Erases the line so another message can be printed; the next update redraws it.
  void clear() {
    if (enabled_) fmt::print(stderr, "\r\033[K");
  }
  void finish() {
    if (enabled_ && !finished_) fmt::print(stderr, "\n");
    finished_ = true;
  }

 private:
  std::size_t total_, first_;
  bool enabled_, finished_ = false;
  std::string abscissa_;
  std::chrono::steady_clock::time_point start_, last_;
};

}  // namespace peridot
