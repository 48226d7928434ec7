#pragma once
#include <filesystem>
#include <vector>
import peridot.io;

// One static LPS solve with its timings and errors against the reference solution.
struct StaticRun {
  peridot::StaticSetup setup;
  peridot::StaticResult result;
  peridot::StaticErrors errors;
  double setup_seconds = 0;
};

StaticRun run_static_once(const peridot::Problem& p);
void write_static_vtu(const std::filesystem::path& dir, const peridot::Problem& p, const StaticRun& run);
void print_static(const StaticRun& run);
// Slope of the least-squares line through (log h, log e): the observed convergence order.
double fitted_order(const std::vector<double>& h, const std::vector<double>& e);
