#pragma once
#include "commands.hpp"
import peridot.problem;

int simulate_osb_static(const peridot::Problem& p, peridot::OsbStaticSetup& s, const RunArgs& args);
