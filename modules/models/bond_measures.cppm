export module peridot.models:bond_measures;
import peridot.std;
import :body;

export namespace peridot {

// Nodal damage phi_i = 1 - (intact weight) / (initial weight), volume-weighted over i's bonds.
void damage(const Body& body, std::vector<double>& phi);
std::vector<double> damage(const Body& body);

// Volume-weighted mean damage over the body, in [0, 1].
double damage_fraction(const Body& body, const std::vector<double>& phi);

// Kinetic energy 1/2 rho |v|^2 V summed over points [J] (2D: J/m).
double kinetic_energy(const Body& body, const VectorField& v);

// Both as exact sums over the listed points only (a rank's owned points): reduced over the
// ranks, their value() is the one-rank figure bit for bit. Damage: {damaged volume, volume}.
ExactSum kinetic_energy_sum(const Body& body, const VectorField& v, std::span<const std::int64_t> points);
std::array<ExactSum, 2> damage_fraction_sums(const Body& body, const std::vector<double>& phi, std::span<const std::int64_t> points);
double damage_fraction_of(const std::array<ExactSum, 2>& sums);

}  // namespace peridot

namespace peridot {

namespace {

// Row by row, as the kernel stores the states: no per-bond index arithmetic.
void damage_on(const Stencil& st, std::vector<double>& phi) {
  const std::size_t nx = std::size_t(st.n[0]), stride = st.row_length();
#pragma omp parallel
  {
    std::vector<double> all(nx), kept(nx);
#pragma omp for schedule(static)
    for (std::int64_t r = 0; r < std::int64_t(st.rows()); ++r) {
      const std::uint8_t* row = st.row_state(std::size_t(r));
      std::fill(all.begin(), all.end(), 0.0);
      std::fill(kept.begin(), kept.end(), 0.0);
      for (std::size_t k = 0; k < st.offsets(); ++k)
        for (std::size_t x = 0; x < nx; ++x) {
          const std::uint8_t b = row[k * stride + x];
          all[x] += b & Stencil::exists ? st.weight[k] : 0.0;
          kept[x] += b & Stencil::intact ? st.weight[k] : 0.0;
        }
      const std::int64_t base = st.row_site(std::size_t(r));
      for (std::size_t x = 0; x < nx; ++x)
        if (const auto i = st.site_point[std::size_t(base) + x]; i >= 0) phi[std::size_t(i)] = all[x] > 0 ? 1.0 - kept[x] / all[x] : 0.0;
    }
  }
}

void damage_on(const BondList& bl, std::vector<double>& phi) {
  const auto n = static_cast<std::int64_t>(phi.size());
#pragma omp parallel for schedule(static)
  for (std::int64_t i = 0; i < n; ++i) {
    double all = 0, kept = 0;
    for (std::int64_t b = bl.offset[i]; b < bl.offset[i + 1]; ++b) {
      const double w = bl.weight_of(b);
      all += w;
      kept += bl.intact[b] ? w : 0.0;
    }
    phi[i] = all > 0 ? 1.0 - kept / all : 0.0;
  }
}

}  // namespace

void damage(const Body& body, std::vector<double>& phi) {
  phi.resize(body.size());
  body.visit_bonds([&](const auto& bonds) { damage_on(bonds, phi); });
}

std::vector<double> damage(const Body& body) {
  std::vector<double> phi;
  damage(body, phi);
  return phi;
}

namespace {

// Every point, or the listed ones.
template <class F>
void for_points(std::size_t n, std::span<const std::int64_t> points, F&& f) {
  if (points.empty())
    for (std::size_t i = 0; i < n; ++i) f(i);
  else
    for (auto i : points) f(std::size_t(i));
}

}  // namespace

std::array<ExactSum, 2> damage_fraction_sums(const Body& body, const std::vector<double>& phi, std::span<const std::int64_t> points) {
  std::array<ExactSum, 2> s;
  for_points(body.size(), points, [&](std::size_t i) {
    s[0] += body.points.volume[i] * phi[i];
    s[1] += body.points.volume[i];
  });
  return s;
}

double damage_fraction_of(const std::array<ExactSum, 2>& sums) {
  const double v = sums[1].value();
  return v > 0 ? sums[0].value() / v : 0.0;
}

double damage_fraction(const Body& body, const std::vector<double>& phi) { return damage_fraction_of(damage_fraction_sums(body, phi, {})); }

ExactSum kinetic_energy_sum(const Body& body, const VectorField& v, std::span<const std::int64_t> points) {
  ExactSum e;
  for_points(body.size(), points, [&](std::size_t i) {
    e += 0.5 * body.density * body.points.volume[i] * (v[0][i] * v[0][i] + v[1][i] * v[1][i] + v[2][i] * v[2][i]);
  });
  return e;
}

double kinetic_energy(const Body& body, const VectorField& v) { return kinetic_energy_sum(body, v, {}).value(); }

}  // namespace peridot
