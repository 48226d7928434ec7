module;
#include <signal.h>

export module peridot.run:stop;
import peridot.std;

export namespace peridot {

// A stop request: the run finishes the step it is in, writes a checkpoint if the deck has one,
// flushes its history and publishes a FAILED summary with the message "interrupted".
// Async-signal-safe: a signal handler may call it.
void request_stop(int signal = 0) noexcept;
bool stop_requested() noexcept;
// The signal that asked for the stop (SIGINT, SIGTERM), 0 for request_stop() without one.
int stop_signal() noexcept;
// Forgets a request, so that one process can run again (tests, a Python session).
void clear_stop() noexcept;

// While alive, SIGINT and SIGTERM request a stop instead of killing the process; a second
// signal of the same kind kills it as the default action would. Restores the previous
// handlers on destruction.
class StopOnSignals {
 public:
  StopOnSignals();
  ~StopOnSignals();
  StopOnSignals(const StopOnSignals&) = delete;
  StopOnSignals& operator=(const StopOnSignals&) = delete;

 private:
  struct sigaction old_int_ {}, old_term_ {};
};

}  // namespace peridot

namespace peridot {

namespace {
// Lock-free on every platform we build for, so the handler may store to them.
std::atomic<int> requested{0};  // 0: none; -1: request_stop() without a signal; else the signal
static_assert(std::atomic<int>::is_always_lock_free);

extern "C" void on_stop_signal(int sig) {
  if (requested.load(std::memory_order_relaxed) == sig) {
    // The second of the same kind: the user insists.
    ::signal(sig, SIG_DFL);
    ::raise(sig);
    return;
  }
  requested.store(sig, std::memory_order_relaxed);
}
}  // namespace

void request_stop(int signal) noexcept { requested.store(signal ? signal : -1, std::memory_order_relaxed); }
bool stop_requested() noexcept { return requested.load(std::memory_order_relaxed) != 0; }
int stop_signal() noexcept { return requested.load(std::memory_order_relaxed) > 0 ? requested.load(std::memory_order_relaxed) : 0; }
void clear_stop() noexcept { requested.store(0, std::memory_order_relaxed); }

StopOnSignals::StopOnSignals() {
  struct sigaction sa {};
  sa.sa_handler = on_stop_signal;
  sigemptyset(&sa.sa_mask);
  sa.sa_flags = SA_RESTART;  // a write interrupted by the signal goes on
  sigaction(SIGINT, &sa, &old_int_);
  sigaction(SIGTERM, &sa, &old_term_);
}

StopOnSignals::~StopOnSignals() {
  sigaction(SIGINT, &old_int_, nullptr);
  sigaction(SIGTERM, &old_term_, nullptr);
}

}  // namespace peridot
