// peridot.analysis: observers that read a run without changing it: fragment counting
// (Boost.Graph connected components over intact bonds) and 2D crack-tip tracking
// (tip position, speed history, branching), 3D crack fronts slice by slice, and the peridynamic stress tensor and force flux.
export module peridot.analysis;
import peridot.std;
export import peridot.models;
export import :fragments;
export import :crack_tip;
export import :crack_front;
export import :stress;
