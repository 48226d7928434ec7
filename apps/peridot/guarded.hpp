#pragma once
#include <cstdio>
#include <exception>
#include <stdexcept>
#include <fmt/core.h>

#include "commands.hpp"
import peridot.run;

// Runs f() and maps failures to exit codes: input problems (DeckError, std::invalid_argument)
// give exit_input_error, anything else exit_runtime_error; the message goes to stderr.
template <class F>
int guarded(F&& f) {
  try {
    return f();
  } catch (const peridot::OtherRankFailed& e) {
    return e.code;  // that rank said why
  } catch (const peridot::DeckError& e) {
    fmt::print(stderr, "error: {}\n", e.what());
    return exit_input_error;
  } catch (const std::invalid_argument& e) {
    fmt::print(stderr, "error: {}\n", e.what());
    return exit_input_error;
  } catch (const std::exception& e) {
    fmt::print(stderr, "error: {}\n", e.what());
    return exit_runtime_error;
  }
}
