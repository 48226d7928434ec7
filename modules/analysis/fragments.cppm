module;
#include <algorithm>
#include <cstdint>
#include <numeric>
#include <stdexcept>
#include <string>
#include <vector>

#include <boost/graph/connected_components.hpp>
#include <boost/property_map/property_map.hpp>

#include "bond_graph.hpp"
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
// connected_components over the bond list as it stands; nothing is copied). A pair of
// points is linked while its bond is intact from either end. Costs one depth-first search
// over the bonds; cheap enough for every output step.
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

}  // namespace

FragmentReport count_fragments(const Body& body, const FragmentOptions& options) {
  validate(body, options);
  const std::size_t n = body.size();
  FragmentReport r;
  r.label.assign(n, -1);
  if (n == 0) return r;

  // Without bonds every point is debris.
  std::vector<std::size_t> component(n);
  std::size_t components = n;
  if (!body.bonds.offset.empty()) {
    const auto& bl = body.bonds;
    const detail::BondGraph g{n, bl.offset.data(), bl.neighbor.data(), bl.intact.data()};
    components = boost::connected_components(
        g, boost::make_iterator_property_map(component.begin(), boost::typed_identity_property_map<std::size_t>()));
  } else {
    std::iota(component.begin(), component.end(), std::size_t(0));
  }

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
