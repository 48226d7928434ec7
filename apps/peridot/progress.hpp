#pragma once
#include <chrono>
#include <cstddef>

// One self-overwriting progress line on a terminal, throttled; silent when stderr is not a tty.
class Progress {
 public:
  // first_step: where a restarted run begins (the ETA counts steps from there).
  Progress(std::size_t total_steps, bool enabled, std::size_t first_step = 0);
  void update(std::size_t step, double time, std::size_t broken);
  // Erases the line so another message can be printed; the next update redraws it.
  void clear();
  void finish();

 private:
  std::size_t total_, first_;
  bool enabled_;
  std::chrono::steady_clock::time_point start_, last_;
};
