module;

#include <omp.h>

#include <boost/graph/compressed_sparse_row_graph.hpp>
#include <boost/graph/connected_components.hpp>

export module peridot.analysis:fragments;
import peridot.std;
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

// A fragment count over N MPI ranks, none of which holds the whole body. Each rank finds the
// pieces of its part (owned points and ghosts, linked by the bonds of the rows it holds) and
// describes them in a FragmentShare, with global piece ids: its offset plus the local piece.
// Rank 0 joins the shares of all ranks: pieces that hold the same point (a ghost here, owned
// there) are one fragment. Counts (fragments, large ones, debris) equal one rank's; masses are
// the same sums in another order. The report has no per-point labels.
struct FragmentShare {
  std::vector<double> pieces;  // per piece with an owned point and two or more points: id, owned points, their mass [kg]
  std::vector<double> joins;   // pairs (this rank's piece of a ghost, the owner's piece of that point), global ids
  double debris = 0, debris_mass = 0, total_mass = 0;  // owned points alone in their piece, and every owned point's mass
};
// The pieces of a rank's local points (`count` of them; one label per local point), linked by
// intact bonds of the held rows only: a ghost whose row is not held is reached from its partners'.
// On a list the held rows are those with bonds; on a stencil, whose ghost rows hold states that
// no force pass updates, `owned` (per local point) says which rows are current.
std::vector<std::uint32_t> piece_labels(const Body& body, std::size_t& count, std::span<const std::uint8_t> owned = {});
// This rank's share: `owned` per local point, `offset` its first global piece id, `owner_piece`
// per local point the global piece id its owner gave it (halo-exchanged; owned points: ignored).
FragmentShare fragment_share(const Body& body, const std::vector<std::uint32_t>& label, std::size_t count, std::span<const std::uint8_t> owned,
                             double offset, std::span<const double> owner_piece);
// Rank 0: every rank's share laid end to end (pieces, joins), and the sums of their scalars.
FragmentReport join_fragment_shares(std::span<const double> pieces, std::span<const double> joins, double debris, double debris_mass,
                                    double total_mass, const FragmentOptions& options = {});

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

// The partners of point i on a CSR list: visit(j, near, linked) with `near` for bonds no longer
// than reach (all of them on a lean list, which stores no lengths; a compact list's lengths come
// from the positions) and linked() whether the pair is linked.
struct ListLinks {
  const BondList& bl;
  const PointCloud& points;  // a compact list's lengths come from them
  double reach;
  template <class Visit>
  void operator()(std::size_t i, Visit&& visit) const {
    const double* len = bl.length.size() == bl.neighbor.size() ? bl.length.data() : nullptr;
    const auto length = [&](std::int64_t b) {
      const auto xi = bond_vector(points, bl, i, b);
      return bond_length(xi[0], xi[1], xi[2]);
    };
    for (std::int64_t b = bl.offset[i]; b < bl.offset[i + 1]; ++b) {
      const bool near = len ? len[b] <= reach : !bl.compact() || length(b) <= reach;
      visit(std::size_t(bl.neighbor[b]), near, [&] { return linked(bl, i, b); });
    }
  }
};

// The same on a stencil: near partners are the sides and diagonals of a lattice cell.
struct StencilLinks {
  const Stencil& st;
  std::span<const std::uint8_t> held = {};  // rows whose states are current (empty: all)
  template <class Visit>
  void operator()(std::size_t i, Visit&& visit) const {
    if (!held.empty() && !held[i]) return;
    const std::size_t first = st.state_index(i, 0), stride = st.row_length();
    for (std::size_t k = 0; k < st.offsets(); ++k) {
      const std::uint8_t b = st.state[first + k * stride];
      if (!(b & Stencil::exists)) continue;
      const auto& o = st.offset[k];
      const bool near = std::abs(o[0]) <= 1 && std::abs(o[1]) <= 1 && std::abs(o[2]) <= 1;
      visit(std::size_t(st.partner(i, k)), near, [b] { return (b & Stencil::intact) != 0; });
    }
  }
};

// Step 1 for the points [lo, hi): the linked near bonds inside the block, in block-local
// numbering, sorted by source (points are visited in order); and which points have partners past the block.
template <class Links>
void skeleton_of(const Links& links, std::size_t lo, std::size_t hi, std::vector<Edge>& edges, std::uint8_t* reaches_out) {
  for (std::size_t i = lo; i < hi; ++i) {
    std::uint8_t out = 0;
    links(i, [&](std::size_t j, bool near, auto&& is_linked) {
      out |= j >= hi;
      if (j < lo || j >= hi || !near) return;
      if (is_linked()) edges.push_back({std::uint32_t(i - lo), std::uint32_t(j - lo)});
    });
    reaches_out[i] = out;
  }
}

// Step 2 for point i: the label pairs of its linked bonds whose ends differ.
// one_sided: some rows are not held (a rank's ghosts), so every bond is looked at from the
// side that holds it instead of from its lower end only.
template <class Links>
void mismatches(const Links& links, const std::uint32_t* label, std::size_t i, std::vector<std::pair<std::uint32_t, std::uint32_t>>& pairs,
                bool one_sided) {
  const std::uint32_t li = label[i];
  links(i, [&](std::size_t j, bool, auto&& is_linked) {
    if ((j <= i && !one_sided) || label[j] == li || !is_linked()) return;  // each pair once
    const std::pair pair{std::min(li, label[j]), std::max(li, label[j])};
    // A block's points meet the same few labels over and over: looking back over the last
    // pairs keeps the list near one entry per pair of blocks instead of several per point
    // (64 B per point on a 2D stencil at delta = 4h, whose bonds span three blocks).
    const auto recent = pairs.end() - std::ptrdiff_t(std::min<std::size_t>(pairs.size(), 8));
    if (std::find(recent, pairs.end(), pair) == pairs.end()) pairs.push_back(pair);
  });
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
template <class Links>
std::vector<std::uint32_t> components_of(const Body& body, const Links& links, std::size_t& count, bool one_sided = false) {
  constexpr std::size_t block_points = 4096;
  const std::size_t n = body.size();
  const auto blocks = std::int64_t((n + block_points - 1) / block_points);
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
      skeleton_of(links, lo, hi, skeleton, reaches_out.data());
      const Graph g(boost::edges_are_sorted, skeleton.begin(), skeleton.end(), Graph::vertices_size_type(hi - lo),
                    skeleton.size());
      mixed[std::size_t(k)] = boost::connected_components(g, label.data() + lo) > 1;
      for (std::size_t i = lo; i < hi; ++i) label[i] += std::uint32_t(lo);  // unique across blocks
    }
    auto& mine = found[std::size_t(omp_get_thread_num())];
#pragma omp for schedule(static)
    for (std::int64_t ii = 0; ii < std::int64_t(n); ++ii) {
      const auto i = std::size_t(ii);
      if (reaches_out[i] || mixed[i / block_points]) mismatches(links, label.data(), i, mine, one_sided);
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
  body.visit_bonds(overloaded{[&](const Stencil& st) { component = components_of(body, StencilLinks{st}, components); },
                              [&](const BondList& bl) {
                                if (bl.offset.empty()) {
                                  std::iota(component.begin(), component.end(), std::uint32_t(0));
                                  return;
                                }
                                // Nearest neighbours: sides and diagonals of a lattice cell (all bonds if h is unknown).
                                const double h = body.points.spacing;
                                component = components_of(body, ListLinks{bl, body.points, h > 0 ? 1.5 * h : std::numeric_limits<double>::infinity()}, components);
                              }});

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

std::vector<std::uint32_t> piece_labels(const Body& body, std::size_t& count, std::span<const std::uint8_t> owned) {
  const std::size_t n = body.size();
  std::vector<std::uint32_t> label(n);
  count = n;
  body.visit_bonds(overloaded{[&](const Stencil& st) { label = components_of(body, StencilLinks{st, owned}, count, true); },
                              [&](const BondList& bl) {
                                if (bl.offset.empty()) {
                                  std::iota(label.begin(), label.end(), std::uint32_t(0));
                                  return;
                                }
                                const double h = body.points.spacing;
                                label = components_of(body, ListLinks{bl, body.points, h > 0 ? 1.5 * h : std::numeric_limits<double>::infinity()}, count, true);
                              }});
  return label;
}

FragmentShare fragment_share(const Body& body, const std::vector<std::uint32_t>& label, std::size_t count, std::span<const std::uint8_t> owned,
                             double offset, std::span<const double> owner_piece) {
  const std::size_t n = body.size();
  if (label.size() != n || owned.size() != n || owner_piece.size() != n)
    throw std::invalid_argument("fragment_share: one label, owned flag and owner piece per local point");
  std::vector<std::size_t> points(count), mine(count);
  std::vector<double> mass(count);
  FragmentShare s;
  for (std::size_t i = 0; i < n; ++i) {
    points[label[i]] += 1;
    if (!owned[i]) continue;
    const double m = body.density * body.points.volume[i];
    mine[label[i]] += 1;
    mass[label[i]] += m;
    s.total_mass += m;
  }
  for (std::size_t c = 0; c < count; ++c) {
    if (mine[c] == 0) continue;  // ghosts only: their owners count them
    if (points[c] >= 2) {
      s.pieces.insert(s.pieces.end(), {offset + double(c), double(mine[c]), mass[c]});
    } else {
      s.debris += 1;
      s.debris_mass += mass[c];
    }
  }
  for (std::size_t i = 0; i < n; ++i)
    if (!owned[i] && mine[label[i]] > 0) s.joins.insert(s.joins.end(), {offset + double(label[i]), owner_piece[i]});
  return s;
}

FragmentReport join_fragment_shares(std::span<const double> pieces, std::span<const double> joins, double debris, double debris_mass,
                                    double total_mass, const FragmentOptions& options) {
  if (!(options.large_mass_fraction >= 0 && options.large_mass_fraction <= 1))
    throw std::invalid_argument("fragments: large_mass_fraction must be in [0, 1], got " + std::to_string(options.large_mass_fraction));
  if (pieces.size() % 3 != 0 || joins.size() % 2 != 0) throw std::invalid_argument("join_fragment_shares: pieces come in threes, joins in pairs");
  const std::size_t m = pieces.size() / 3;
  // Pieces by global id: the ranks' ids are disjoint and each rank's are increasing.
  std::vector<std::pair<double, std::uint32_t>> by_id(m);
  for (std::size_t k = 0; k < m; ++k) by_id[k] = {pieces[3 * k], std::uint32_t(k)};
  std::sort(by_id.begin(), by_id.end());
  const auto index_of = [&](double id) -> std::int64_t {
    const auto it = std::lower_bound(by_id.begin(), by_id.end(), std::pair{id, std::uint32_t(0)});
    return it != by_id.end() && it->first == id ? std::int64_t(it->second) : -1;
  };
  std::vector<Edge> edges;
  for (std::size_t k = 0; k + 1 < joins.size(); k += 2) {
    const auto a = index_of(joins[k]), b = index_of(joins[k + 1]);
    if (a < 0 || b < 0 || a == b) continue;  // an owner that sees its point alone counts it as debris
    edges.push_back({std::uint32_t(a), std::uint32_t(b)});
    edges.push_back({std::uint32_t(b), std::uint32_t(a)});
  }
  std::sort(edges.begin(), edges.end());
  edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
  const Graph g(boost::edges_are_sorted, edges.begin(), edges.end(), Graph::vertices_size_type(m), edges.size());
  std::vector<std::uint32_t> root(m);
  const std::size_t fragments = m ? boost::connected_components(g, root.data()) : 0;
  std::vector<Fragment> joined(fragments);
  for (std::size_t k = 0; k < m; ++k) {
    joined[root[k]].nodes += std::size_t(pieces[3 * k + 1]);
    joined[root[k]].mass += pieces[3 * k + 2];
  }
  FragmentReport r;
  r.debris = std::size_t(debris);
  r.debris_mass = debris_mass;
  r.total_mass = total_mass;
  std::sort(joined.begin(), joined.end(), [](const Fragment& a, const Fragment& b) { return a.mass > b.mass; });
  const double large = options.large_mass_fraction * total_mass;
  for (const auto& f : joined) r.large += f.mass > large;
  r.fragments = std::move(joined);
  r.count = r.fragments.size();
  return r;
}

}  // namespace peridot
