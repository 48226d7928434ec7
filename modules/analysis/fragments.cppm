module;
#include <algorithm>
#include <cstdint>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <string>
#include <vector>

#include <omp.h>

#include <boost/graph/compressed_sparse_row_graph.hpp>
#include <boost/graph/connected_components.hpp>

export module peridot.analysis:fragments;
import peridot.models;

export namespace peridot {

struct FragmentOptions {
  // A fragment is "large" when its mass exceeds this fraction of the body's total mass
  // (debris included). Must lie in [0, 1].
  double large_mass_fraction = 0.01;
};

struct Fragment {
  std::size_t nodes = 0;
  double mass = 0;  // density * sum of nodal volumes [kg] (2D: kg/m, per unit thickness)
};

struct FragmentReport {
  std::size_t count = 0;        // fragments: connected pieces of >= 2 points
  std::size_t large = 0;        // fragments heavier than large_mass_fraction of the total
  std::size_t debris = 0;       // isolated points: every bond broken, or no bonds at all
  double debris_mass = 0;       // [kg] (2D: kg/m)
  double total_mass = 0;        // [kg] (2D: kg/m), fragments plus debris
  std::vector<Fragment> fragments;  // sorted by mass, heaviest first
  std::vector<std::int32_t> label;  // per point: index into fragments, -1 for debris
};

// Splits the body into pieces held together by intact bonds (Boost.Graph
// connected_components over the bond list as it stands). A pair of points is linked while
// its bond is intact from either end; bonds must be stored from both ends, as build_bonds
// does. Parallel (OpenMP) and cheaper than a force pass: see peridot-bench-analysis.
FragmentReport count_fragments(const Body& body, const FragmentOptions& options = {});

}  // namespace peridot

namespace peridot {

namespace {

void validate(const Body& body, const FragmentOptions& o) {
  if (!(o.large_mass_fraction >= 0 && o.large_mass_fraction <= 1))
    throw std::invalid_argument("fragments: large_mass_fraction must be in [0, 1], got " +
                                std::to_string(o.large_mass_fraction));
  const auto& bl = body.bonds;
  if (!bl.offset.empty() && bl.offset.size() != body.size() + 1)
    throw std::invalid_argument("fragments: bond list has " + std::to_string(bl.points()) + " points, body has " +
                                std::to_string(body.size()));
  if (bl.intact.size() != bl.neighbor.size())
    throw std::invalid_argument("fragments: bond list intact mask and neighbor list differ in size");
}

// A pair stays linked while its bond is intact from either end. Models break both ends
// together, so the reverse bond is searched only for the rare bonds broken on this side.
bool linked(const BondList& bl, std::size_t i, std::int64_t b) {
  if (bl.intact[b]) return true;
  const auto j = std::size_t(bl.neighbor[b]);
  for (std::int64_t r = bl.offset[j]; r < bl.offset[j + 1]; ++r)
    if (std::size_t(bl.neighbor[r]) == i) return bl.intact[r] != 0;
  return false;
}

using Graph = boost::compressed_sparse_row_graph<boost::directedS, boost::no_property, boost::no_property,
                                                 boost::no_property, std::uint32_t, std::size_t>;
using Edge = std::pair<std::uint32_t, std::uint32_t>;

// Step 1 for the points [lo, hi): the linked bonds inside the block no longer than reach
// (all of them without lengths), in block-local numbering, sorted by source; and which
// points have partners past the block.
void skeleton_of(const BondList& bl, std::size_t lo, std::size_t hi, double reach, std::vector<Edge>& edges,
                 std::uint8_t* reaches_out) {
  const std::int64_t* off = bl.offset.data();
  const std::int32_t* nb = bl.neighbor.data();
  const double* len = bl.length.size() == bl.neighbor.size() ? bl.length.data() : nullptr;
  for (std::size_t i = lo; i < hi; ++i) {
    const std::int64_t end = off[i + 1];
    std::uint8_t out = 0;
    for (std::int64_t b = off[i]; b < end; ++b) {
      const auto j = std::size_t(nb[b]);
      out |= j >= hi;
      if (j < lo || j >= hi || (len && len[b] > reach)) continue;
      if (linked(bl, i, b)) edges.push_back({std::uint32_t(i - lo), std::uint32_t(j - lo)});
    }
    reaches_out[i] = out;
  }
}

// Step 2 for point i: the label pairs of its linked bonds whose ends differ.
void mismatches(const BondList& bl, const std::uint32_t* label, std::size_t i,
                std::vector<std::pair<std::uint32_t, std::uint32_t>>& pairs) {
  const std::int32_t* nb = bl.neighbor.data();
  const std::uint32_t li = label[i];
  const std::int64_t end = bl.offset[i + 1];
  for (std::int64_t b = bl.offset[i]; b < end; ++b) {
    const auto j = std::size_t(nb[b]);
    if (j <= i || label[j] == li || !linked(bl, i, b)) continue;  // each pair once
    const std::pair pair{std::min(li, label[j]), std::max(li, label[j])};
    if (pairs.empty() || pairs.back() != pair) pairs.push_back(pair);  // runs repeat the pair
  }
}

// Connected components of the points linked by bonds, in three exact steps:
//  1. per block of consecutive points, in parallel: Boost connected_components over a
//     skeleton, the linked bonds to nearest neighbours (sides and diagonals of a lattice
//     cell, about 1/6 of the bonds in 2D at delta = 4 h) inside the block;
//  2. in parallel: every linked bond whose ends got different labels gives a pair (only
//     bonds leaving a block can, where the block's skeleton was connected);
//  3. Boost connected_components over the labels joined by those pairs (a small graph).
// A label only ever holds connected points and step 2 sees every linked bond that could join
// two labels, so the result is that of one search over all bonds (and independent of the
// thread count), at a fraction of the cost: depth-first search is latency-bound, so it walks
// a small graph built in one sweep in memory order, and the other bonds are read in order,
// in parallel. Blocks stay small so that the search's own buffers (its stack grows with the
// block) are recycled by malloc rather than mapped afresh: page faults cost as much as the
// search on 10^6 bonds.
std::vector<std::uint32_t> components_of(const Body& body, std::size_t& count) {
  constexpr std::size_t block_points = 4096;
  const std::size_t n = body.size();
  const auto blocks = std::int64_t((n + block_points - 1) / block_points);
  // Nearest neighbours: sides and diagonals of a lattice cell (all bonds if h is unknown).
  const double h = body.points.spacing;
  const double reach = h > 0 ? 1.5 * h : std::numeric_limits<double>::infinity();
  std::vector<std::uint32_t> label(n);
  std::vector<std::uint8_t> reaches_out(n), mixed(static_cast<std::size_t>(blocks));  // mixed: several labels
  std::vector<std::vector<std::pair<std::uint32_t, std::uint32_t>>> found(static_cast<std::size_t>(omp_get_max_threads()));
#pragma omp parallel
  {
    std::vector<Edge> skeleton;
#pragma omp for schedule(dynamic)
    for (std::int64_t k = 0; k < blocks; ++k) {
      const std::size_t lo = std::size_t(k) * block_points, hi = std::min(n, lo + block_points);
      skeleton.clear();
      skeleton_of(body.bonds, lo, hi, reach, skeleton, reaches_out.data());
      const Graph g(boost::edges_are_sorted, skeleton.begin(), skeleton.end(), Graph::vertices_size_type(hi - lo),
                    skeleton.size());
      mixed[std::size_t(k)] = boost::connected_components(g, label.data() + lo) > 1;
      for (std::size_t i = lo; i < hi; ++i) label[i] += std::uint32_t(lo);  // unique across blocks
    }
    auto& mine = found[std::size_t(omp_get_thread_num())];
#pragma omp for schedule(static)
    for (std::int64_t ii = 0; ii < std::int64_t(n); ++ii) {
      const auto i = std::size_t(ii);
      if (reaches_out[i] || mixed[i / block_points]) mismatches(body.bonds, label.data(), i, mine);
    }
  }

  // Number the labels densely, then join them along the pairs.
  std::vector<std::uint32_t> dense(n, std::numeric_limits<std::uint32_t>::max());  // label -> dense id
  std::uint32_t labels = 0;
  for (std::size_t i = 0; i < n; ++i)
    if (dense[label[i]] == std::numeric_limits<std::uint32_t>::max()) dense[label[i]] = labels++;
  std::vector<Edge> joins;
  for (const auto& f : found)
    for (const auto& [a, b] : f) {
      joins.push_back({dense[a], dense[b]});
      joins.push_back({dense[b], dense[a]});
    }
  std::sort(joins.begin(), joins.end());
  joins.erase(std::unique(joins.begin(), joins.end()), joins.end());
  const Graph quotient(boost::edges_are_sorted, joins.begin(), joins.end(), labels, joins.size());
  std::vector<std::uint32_t> joined(labels);
  count = boost::connected_components(quotient, joined.data());
  for (std::size_t i = 0; i < n; ++i) label[i] = joined[dense[label[i]]];
  return label;
}

}  // namespace

FragmentReport count_fragments(const Body& body, const FragmentOptions& options) {
  validate(body, options);
  const std::size_t n = body.size();
  FragmentReport r;
  r.label.assign(n, -1);
  if (n == 0) return r;

  // Without bonds every point is debris.
  std::size_t components = n;
  std::vector<std::uint32_t> component(n);
  if (body.bonds.offset.empty())
    std::iota(component.begin(), component.end(), std::uint32_t(0));
  else
    component = components_of(body, components);

  std::vector<Fragment> pieces(components);
  for (std::size_t i = 0; i < n; ++i) {
    const double m = body.density * body.points.volume[i];
    pieces[component[i]].nodes += 1;
    pieces[component[i]].mass += m;
    r.total_mass += m;
  }

  // Keep pieces of two or more points as fragments, heaviest first (ties by component id,
  // so labels are reproducible); single points are debris.
  std::vector<std::size_t> order;
  order.reserve(components);
  for (std::size_t c = 0; c < components; ++c) {
    if (pieces[c].nodes >= 2) {
      order.push_back(c);
    } else {
      r.debris += 1;
      r.debris_mass += pieces[c].mass;
    }
  }
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    return pieces[a].mass != pieces[b].mass ? pieces[a].mass > pieces[b].mass : a < b;
  });

  std::vector<std::int32_t> fragment_of(components, -1);
  r.fragments.reserve(order.size());
  const double large = options.large_mass_fraction * r.total_mass;
  for (std::size_t c : order) {
    fragment_of[c] = std::int32_t(r.fragments.size());
    r.fragments.push_back(pieces[c]);
    r.large += pieces[c].mass > large;
  }
  r.count = r.fragments.size();
  for (std::size_t i = 0; i < n; ++i) r.label[i] = fragment_of[component[i]];
  return r;
}

}  // namespace peridot
