#include <catch2/catch.hpp>
#include <cmath>
#include <string>
#include <variant>
#include "../support/deck_text.hpp"
import peridot.problem;

using namespace peridot;

namespace {

// A small valid deck; tests replace one line to break it.
const std::string valid = R"(name: plate
dimension: 2
geometry:
  body:
    difference:
      - rectangle: {min: [0, 0], max: [0.01, 0.004]}
      - disk: {center: [0.005, 0.002], radius: 0.001}
  cracks:
    - segment: {from: [0, 0.002], to: [0.003, 0.002]}
discretization:
  spacing: 2.5e-4
  horizon_factor: 4
material:
  youngs_modulus: 72e9
  density: 2440
  fracture_energy: 3.8
boundaries:
  - name: top
    type: traction
    region: {layer: {side: +y, count: 1}}
    value: [0, 2e6]
    history: {type: ramp, start: 0, end: 1e-6}
solver:
  end_time: 1e-6
)";

std::string with(const std::string& from, const std::string& to) { return deck_text::replaced(valid, from, to); }

}  // namespace

TEST_CASE("a valid deck parses with its units and defaults") {
  const Problem p = parse_deck(valid);
  CHECK(p.dim == 2);
  CHECK(p.horizon == Approx(1e-3));
  CHECK(p.material.kinematics == Kinematics::plane_stress);
  REQUIRE(p.boundaries.size() == 1);
  // The traction is spread over one layer of thickness h as a body force density.
  CHECK(p.boundaries[0].value[1] == Approx(2e6 / 2.5e-4));
  CHECK(p.solver.safety == 0.8);
  const Setup s = setup(p);
  CHECK(s.body.size() > 0);
  CHECK(s.boundaries[0].points.size() == 40);
}

TEST_CASE("malformed YAML is reported with its line") {
  CHECK_THROWS_WITH(parse_deck("name: [unclosed\n  x: 1"), Catch::Contains("malformed YAML") && Catch::Contains("line"));
}

TEST_CASE("an unknown key is an error naming the key and the allowed ones") {
  CHECK_THROWS_WITH(parse_deck(with("  density: 2440", "  density: 2440\n  colour: red")),
                    Catch::Contains("material: unknown key 'colour'") && Catch::Contains("youngs_modulus"));
}

TEST_CASE("a negative or zero horizon is rejected with the allowed range") {
  CHECK_THROWS_WITH(parse_deck(with("horizon_factor: 4", "horizon: -1e-3")),
                    Catch::Contains("discretization.horizon = -1e-3") && Catch::Contains("> 0"));
  CHECK_THROWS_WITH(parse_deck(with("horizon_factor: 4", "horizon: 0")), Catch::Contains("discretization.horizon = 0"));
  CHECK_THROWS_WITH(parse_deck(with("horizon_factor: 4", "horizon_factor: -4")), Catch::Contains("discretization.horizon_factor"));
}

TEST_CASE("a spacing larger than the horizon is rejected") {
  CHECK_THROWS_WITH(parse_deck(with("horizon_factor: 4", "horizon: 1e-4")),
                    Catch::Contains("discretization.horizon") && Catch::Contains("must be >= spacing"));
}

TEST_CASE("a geometry with no lattice points is rejected") {
  const auto p = parse_deck(with("- rectangle: {min: [0, 0], max: [0.01, 0.004]}", "- rectangle: {min: [0, 0], max: [0.01, 0.004]}\n      - rectangle: {min: [-1, -1], max: [1, 1]}"));
  CHECK_THROWS_WITH(setup(p), Catch::Contains("geometry.body") && Catch::Contains("no lattice points"));
}

TEST_CASE("a missing deck file is reported by name") {
  CHECK_THROWS_WITH(read_deck("/nonexistent/deck.yaml"), Catch::Contains("/nonexistent/deck.yaml") && Catch::Contains("cannot open"));
}

TEST_CASE("NaN and infinite numbers are rejected") {
  CHECK_THROWS_WITH(parse_deck(with("youngs_modulus: 72e9", "youngs_modulus: .nan")),
                    Catch::Contains("material.youngs_modulus") && Catch::Contains("finite"));
  CHECK_THROWS_WITH(parse_deck(with("end_time: 1e-6", "end_time: .inf")), Catch::Contains("solver.end_time"));
}

TEST_CASE("wrong types, shapes and choices are rejected with the field name") {
  CHECK_THROWS_WITH(parse_deck(with("density: 2440", "density: heavy")), Catch::Contains("material.density = 'heavy': not a number"));
  CHECK_THROWS_WITH(parse_deck(with("type: traction", "type: pressure")), Catch::Contains("boundaries[0].type = 'pressure'"));
  CHECK_THROWS_WITH(parse_deck(with("disk: {center", "sphere: {center")), Catch::Contains("3D shape in a 2D problem"));
  CHECK_THROWS_WITH(parse_deck(with("dimension: 2", "dimension: 4")), Catch::Contains("dimension = 4"));
  CHECK_THROWS_WITH(parse_deck(with("value: [0, 2e6]", "value: [0, 2e6, 1]")), Catch::Contains("boundaries[0].value"));
  CHECK_THROWS_WITH(parse_deck(with("  end_time: 1e-6\n", "")), Catch::Contains("solver.end_time: required"));
  CHECK_THROWS_WITH(parse_deck(""), Catch::Contains("empty"));
  CHECK_THROWS_WITH(parse_deck(with("horizon_factor: 4", "horizon_factor: 4\n  list_precision: half")),
                    Catch::Contains("discretization.list_precision = 'half'"));
}

TEST_CASE("a boundary region that selects no point is rejected") {
  const auto p = parse_deck(with("region: {layer: {side: +y, count: 1}}\n    value: [0, 2e6]",
                                 "region: {layer: {side: +y, count: 1}}\n    value: [0, 2e6]\n  - name: nowhere\n    type: displacement\n    region: {disk: {center: [5, 5], radius: 0.1}}\n    value: [0, 0]"));
  CHECK_THROWS_WITH(setup(p), Catch::Contains("'nowhere'") && Catch::Contains("selects no point"));
}

TEST_CASE("the shipped crack-branching decks describe the specimen of seed 000 Sec. 6.1 and Table 1") {
  // A 0.1 m x 0.04 m plate with a 0.05 m pre-crack from the left edge at mid-height, sigma = 2 MPa
  // on the top and bottom edges; glass with E = 72 GPa, rho = 2440 kg/m^3, G0 = 3.8 J/m^2.
  for (const char* name : {"crack_branching_2d.yaml", "crack_branching_2d_fine.yaml", "crack_branching_3d.yaml"}) {
    INFO(name);
    const Problem p = read_deck(std::string(PERIDOT_SOURCE_DIR) + "/data/decks/" + name);
    const auto box = p.body.bounds();
    CHECK(box.hi[0] - box.lo[0] == Approx(0.1).epsilon(1e-12));
    CHECK(box.hi[1] - box.lo[1] == Approx(0.04).epsilon(1e-12));
    const double mid = 0.5 * (box.lo[1] + box.hi[1]);
    REQUIRE(p.cracks.size() == 1);
    Vec3 from{}, along{};
    if (const auto* c = std::get_if<CrackSegment>(&p.cracks[0])) from = c->a, along = c->b - c->a;
    if (const auto* c = std::get_if<CrackRectangle>(&p.cracks[0])) {
      from = c->origin, along = c->edge1;
      CHECK(c->edge2[0] == 0.0);
      CHECK(c->edge2[1] == 0.0);
      CHECK(std::abs(c->edge2[2]) >= box.hi[2] - box.lo[2]);  // through the thickness
    }
    CHECK(from[0] <= box.lo[0]);
    CHECK(from[0] + along[0] == Approx(box.lo[0] + 0.05).epsilon(1e-12));
    CHECK(from[1] == Approx(mid).epsilon(1e-12));
    CHECK(along[1] == 0.0);
    CHECK(p.material.youngs_modulus == 72e9);
    CHECK(p.material.density == 2440);
    CHECK(p.material.fracture_energy == 3.8);
    // The tractions, spread over one lattice layer as body forces: +-2 MPa times the layer's 1/h.
    REQUIRE(p.boundaries.size() == 2);
    double pull = 0;
    for (const auto& b : p.boundaries) {
      CHECK(b.kind == BoundaryKind::body_force);
      CHECK(b.value[0] == 0.0);
      CHECK(std::abs(b.value[1]) * p.lattice.spacing == Approx(2e6).epsilon(1e-12));
      pull += b.value[1];
      if (b.name == "top") CHECK(b.value[1] > 0);  // tension
    }
    CHECK(pull == 0.0);  // the other pulls down
  }
}

TEST_CASE("damage counts the bonds a pre-crack cuts, as other codes do, unless the deck excludes them") {
  // The crack runs along y = 0.002 m for x < 0.003 m; delta = 1 mm, h = 0.25 mm.
  for (bool counted : {true, false}) {
    INFO("precrack_damage: " << counted);
    const Setup s = setup(parse_deck(with("  cracks:", std::string("  precrack_damage: ") + (counted ? "true" : "false") + "\n  cracks:")));
    const auto phi = damage(s.body);
    const auto& x = s.body.points.x;
    std::size_t near = 0;
    for (std::size_t i = 0; i < s.body.size(); ++i) {
      const double dy = std::abs(x[1][i] - 0.002);
      if (dy > 1.01e-3 || x[0][i] > 0.00401) REQUIRE(phi[i] == 0.0);  // no bond of i crosses the crack
      if (dy < 2.6e-4 && x[0][i] < 0.0025) {
        ++near;
        if (counted) CHECK(phi[i] > 0.3);  // about half of a point's bonds cross a crack next to it
        else CHECK(phi[i] == 0.0);
      }
    }
    CHECK(near > 10);
  }
}
