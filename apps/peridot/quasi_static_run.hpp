#pragma once
#include "commands.hpp"
import peridot.problem;

int simulate_quasi_static(const peridot::Problem& p, peridot::QuasiStaticSetup& s, const RunArgs& args);
