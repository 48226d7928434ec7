export module peridot.run:checkpointing;
import peridot.std;
import peridot.problem;

// Restart checkpoints of explicit runs: the bridge between a run (deck, body, state, solver
// counters) and the plain Checkpoint that peridot.io writes and reads.
export namespace peridot {

// The checkpoint of a run after state.step; the bond state is the body's mask.
Checkpoint make_checkpoint(const Problem& p, const Setup& s, const State& state, double external_work, std::size_t broken);

// Reads a checkpoint and checks that it belongs to this deck and set-up: deck name, point
// and bond counts, dimension, scheme, dt, the deck's content hash, a step within the run and
// bond states the deck's pre-cracks allow. Throws DeckError naming what differs (an input
// error: exit 2, before any output).
Checkpoint read_restart(const std::filesystem::path& file, const Problem& p, const Setup& s);

// Moves the checkpoint's u, v, f, time, step and bond mask into the run.
void restore_run(Checkpoint& c, Body& body, State& state);

}  // namespace peridot

namespace peridot {

namespace {

std::string scheme_name(ExplicitScheme s) { return s == ExplicitScheme::central_difference ? "central_difference" : "velocity_verlet"; }

// Bond states a checkpoint holds: one per directed bond of a list, one per (point, offset) of a stencil.
std::size_t bond_slots(const Body& body) { return body.bond_states().size(); }

}  // namespace

Checkpoint make_checkpoint(const Problem& p, const Setup& s, const State& state, double external_work, std::size_t broken) {
  Checkpoint c;
  c.deck_name = p.name;
  c.deck_hash = p.content_hash;
  c.dim = s.body.dim();
  c.points = s.body.size();
  c.bonds = bond_slots(s.body);
  c.dt = s.time_step.dt;
  c.scheme = scheme_name(p.solver.scheme);
  c.step = state.step;
  c.time = state.time;
  c.u = state.u;
  c.v = state.v;
  c.f = state.f;
  const auto states = s.body.bond_states();
  c.bond_state.assign(states.begin(), states.end());
  c.external_work = external_work;
  c.broken = broken;
  return c;
}

Checkpoint read_restart(const std::filesystem::path& file, const Problem& p, const Setup& s) {
  Checkpoint c;
  try {
    c = read_checkpoint(file);
  } catch (const std::runtime_error& e) {
    throw DeckError(fmt::format("restart: {}", e.what()));
  }
  const auto fail = [&](const std::string& what) { throw DeckError(fmt::format("restart {}: {}", file.string(), what)); };
  if (c.deck_name != p.name || c.points != s.body.size())
    fail(fmt::format("checkpoint is from deck '{}' with {} points; this deck '{}' has {} points", c.deck_name, c.points, p.name, s.body.size()));
  if (c.dim != s.body.dim()) fail(fmt::format("checkpoint is {}D; this deck is {}D", c.dim, s.body.dim()));
  if (c.bonds != bond_slots(s.body))
    fail(fmt::format("checkpoint has {} bond states; this deck has {} (same {} points: horizon, quadrature, cracks or discretization.bonds "
                     "differ)",
                     c.bonds, bond_slots(s.body), c.points));
  if (c.scheme != scheme_name(p.solver.scheme))
    fail(fmt::format("checkpoint was written with solver.scheme = '{}'; this deck has '{}'", c.scheme, scheme_name(p.solver.scheme)));
  if (c.dt != s.time_step.dt)
    fail(fmt::format("checkpoint has dt = {:.17g} s; this deck has dt = {:.17g} s (solver.dt, solver.safety or the material differ)", c.dt,
                     s.time_step.dt));
  if (c.deck_hash != p.content_hash)
    fail(fmt::format("checkpoint's deck content hash {:016x} differs from this deck's {:016x}: a key other than name, output.* and "
                     "solver.end_time changed since it was written",
                     c.deck_hash, p.content_hash));
  if (c.step > s.time_step.steps)
    fail(fmt::format("checkpoint is at step {} (t = {:.6e} s), past this deck's end: {} steps to solver.end_time = {:g} s", c.step, c.time,
                     s.time_step.steps, p.solver.end_time));
  s.body.visit_bonds(overloaded{
      [&](const Stencil& st) {
        // Stencil states carry an `exists` bit that fracture never changes: it must match this deck's.
        const auto& fresh = st.state;
        for (std::size_t b = 0; b < c.bond_state.size(); ++b)
          if (c.bond_state[b] > 3 || (c.bond_state[b] & Stencil::exists) != (fresh[b] & Stencil::exists) ||
              (c.bond_state[b] & Stencil::intact) > (fresh[b] & Stencil::intact))
            fail(fmt::format("bond_state[{}] = {} does not fit this deck's stencil (state {})", b, int(c.bond_state[b]), int(fresh[b])));
      },
      [&](const BondList& bl) {
        // Fracture only ever breaks bonds: one the deck's pre-cracks cut can't be intact again.
        const auto& fresh = bl.intact;
        for (std::size_t b = 0; b < c.bond_state.size(); ++b) {
          if (c.bond_state[b] > 1) fail(fmt::format("bond_state[{}] = {}; a bond is 0 (broken) or 1 (intact)", b, int(c.bond_state[b])));
          if (c.bond_state[b] > fresh[b])
            fail(fmt::format("bond_state[{}] is intact, but this deck's pre-cracks cut that bond (geometry.cracks differ?)", b));
        }
      }});
  return c;
}

void restore_run(Checkpoint& c, Body& body, State& state) {
  for (int k = 0; k < 3; ++k) {
    state.u[k] = std::move(c.u[k]);
    state.v[k] = std::move(c.v[k]);
    state.f[k] = std::move(c.f[k]);
  }
  state.time = c.time;
  state.step = std::size_t(c.step);
  const auto states = body.bond_states();
  if (c.bond_state.size() != states.size())
    throw std::logic_error(fmt::format("restore_run: {} bond states for a body of {} (read_restart checks this)", c.bond_state.size(), states.size()));
  std::copy(c.bond_state.begin(), c.bond_state.end(), states.begin());
}

}  // namespace peridot
