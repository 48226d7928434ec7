#include "progress.hpp"

#include <unistd.h>

#include <cstdio>
#include <fmt/core.h>

Progress::Progress(std::size_t total_steps, bool enabled, std::size_t first_step)
    : total_(total_steps), first_(first_step), enabled_(enabled && isatty(STDERR_FILENO)),
      start_(std::chrono::steady_clock::now()), last_(start_) {}

void Progress::update(std::size_t step, double time, std::size_t broken) {
  if (!enabled_) return;
  const auto now = std::chrono::steady_clock::now();
  if (now - last_ < std::chrono::milliseconds(250) && step != total_) return;
  last_ = now;
  const double elapsed = std::chrono::duration<double>(now - start_).count();
  const double eta = step > first_ ? elapsed * double(total_ - step) / double(step - first_) : 0.0;
  fmt::print(stderr, "\r  step {:>8}/{}  t = {:.4e} s  ETA {:>6.1f} s  broken bonds {:>9}   ", step, total_, time, eta, broken);
  std::fflush(stderr);
}

void Progress::clear() {
  if (enabled_) fmt::print(stderr, "\r\033[K");
}

void Progress::finish() {
  if (enabled_) fmt::print(stderr, "\n");
}
