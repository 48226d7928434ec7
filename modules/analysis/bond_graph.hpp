// Boost.Graph view of a CSR bond list (private to peridot.analysis; included from the global
// module fragment, so it sees raw arrays rather than module types).
//
// Vertices are points; the out-edges of i are the bonds of i that still link two points.
// Nothing is copied, so fragment counting costs one depth-first search over the bonds.
#pragma once

#include <cstddef>
#include <cstdint>
#include <limits>
#include <utility>

#include <boost/graph/graph_traits.hpp>
#include <boost/graph/properties.hpp>
#include <boost/iterator/counting_iterator.hpp>
#include <boost/iterator/iterator_facade.hpp>
#include <boost/property_map/property_map.hpp>

namespace peridot::detail {

struct BondGraph {
  std::size_t n = 0;
  const std::int64_t* offset = nullptr;    // n + 1
  const std::int32_t* neighbor = nullptr;
  const std::uint8_t* intact = nullptr;

  // A pair stays linked while its bond is intact from either end. Models break both ends
  // together, so the reverse bond is searched only for the rare bonds broken on this side;
  // the rule is symmetric, which is what makes the graph undirected.
  bool linked(std::size_t i, std::int64_t b) const {
    if (intact[b]) return true;
    const std::int32_t j = neighbor[b];
    for (std::int64_t r = offset[j]; r < offset[j + 1]; ++r)
      if (std::size_t(neighbor[r]) == i) return intact[r] != 0;
    return false;
  }
};

struct BondEdge {
  std::size_t source = 0;
  std::int64_t bond = 0;
  friend bool operator==(const BondEdge& a, const BondEdge& b) { return a.source == b.source && a.bond == b.bond; }
  friend bool operator!=(const BondEdge& a, const BondEdge& b) { return !(a == b); }
};

// Walks the bonds of one point, skipping those that no longer link.
class BondEdgeIterator
    : public boost::iterator_facade<BondEdgeIterator, BondEdge, std::forward_iterator_tag, BondEdge> {
 public:
  BondEdgeIterator() = default;
  BondEdgeIterator(const BondGraph* g, std::size_t i, std::int64_t b) : g_(g), i_(i), b_(b) { skip(); }

 private:
  friend class boost::iterator_core_access;
  void skip() {
    const std::int64_t end = g_->offset[i_ + 1];
    while (b_ < end && !g_->linked(i_, b_)) ++b_;
  }
  void increment() {
    ++b_;
    skip();
  }
  bool equal(const BondEdgeIterator& o) const { return b_ == o.b_; }
  BondEdge dereference() const { return {i_, b_}; }

  const BondGraph* g_ = nullptr;
  std::size_t i_ = 0;
  std::int64_t b_ = 0;
};

using BondVertexIterator = boost::counting_iterator<std::size_t>;

}  // namespace peridot::detail

namespace boost {

template <>
struct graph_traits<peridot::detail::BondGraph> {
  using vertex_descriptor = std::size_t;
  using edge_descriptor = peridot::detail::BondEdge;
  using directed_category = undirected_tag;
  using edge_parallel_category = disallow_parallel_edge_tag;
  struct traversal_category : incidence_graph_tag, vertex_list_graph_tag {};
  using vertex_iterator = peridot::detail::BondVertexIterator;
  using out_edge_iterator = peridot::detail::BondEdgeIterator;
  using vertices_size_type = std::size_t;
  using edges_size_type = std::size_t;
  using degree_size_type = std::size_t;
  static vertex_descriptor null_vertex() { return std::numeric_limits<std::size_t>::max(); }
};

template <>
struct property_map<peridot::detail::BondGraph, vertex_index_t> {
  using type = typed_identity_property_map<std::size_t>;
  using const_type = type;
};

}  // namespace boost

namespace peridot::detail {

// The free functions Boost.Graph finds by argument-dependent lookup.
inline std::pair<BondVertexIterator, BondVertexIterator> vertices(const BondGraph& g) {
  return {BondVertexIterator(0), BondVertexIterator(g.n)};
}
inline std::size_t num_vertices(const BondGraph& g) { return g.n; }
inline std::pair<BondEdgeIterator, BondEdgeIterator> out_edges(std::size_t i, const BondGraph& g) {
  return {BondEdgeIterator(&g, i, g.offset[i]), BondEdgeIterator(&g, i, g.offset[i + 1])};
}
inline std::size_t out_degree(std::size_t i, const BondGraph& g) {
  std::size_t d = 0;
  for (std::int64_t b = g.offset[i]; b < g.offset[i + 1]; ++b) d += g.linked(i, b);
  return d;
}
inline std::size_t source(const BondEdge& e, const BondGraph&) { return e.source; }
inline std::size_t target(const BondEdge& e, const BondGraph& g) { return std::size_t(g.neighbor[e.bond]); }
inline boost::typed_identity_property_map<std::size_t> get(boost::vertex_index_t, const BondGraph&) { return {}; }

}  // namespace peridot::detail
