#pragma once
#include <chrono>
#include <cstddef>

// One self-overwriting progress line on a terminal, throttled; silent when stderr is not a tty.
class Progress {
 public:
  Progress(std::size_t total_steps, bool enabled);
  void update(std::size_t step, double time, std::size_t broken);
  void finish();

 private:
  std::size_t total_;
  bool enabled_;
  std::chrono::steady_clock::time_point start_, last_;
};
