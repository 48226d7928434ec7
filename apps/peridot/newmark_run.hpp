#pragma once
#include "commands.hpp"
import peridot.problem;

// Prints the set-up of a dynamic LPS run (explicit or implicit).
void print_lps_setup(const peridot::Problem& p, const peridot::Body& body, const peridot::Lps& model);
int simulate_newmark(const peridot::Problem& p, peridot::NewmarkSetup& s, const RunArgs& args);
