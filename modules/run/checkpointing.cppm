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

// The same for one MPI rank's part of a run, from a checkpoint in parts or a whole one: reads
// only the part's owned points (read_checkpoint_points, read_whole_checkpoint_points) and checks
// them against the part's rows, and the checkpoint's totals against the whole body's
// (slab.global_size, slab.bond_starts). Collective for a whole checkpoint (its rows' starts
// are summed over the ranks); a checkpoint in parts each rank reads and checks on its own.
Checkpoint read_restart_part(const std::filesystem::path& file, const Problem& p, const Setup& part);

// The box of a part's owned points' reference positions (lo x, y, z, hi x, y, z), as checkpoint
// parts record it (CheckpointPart::box) and a restart looks for its points.
std::array<double, 6> owned_box(const Setup& part);

// Moves the checkpoint's u, v, f, time, step and bond mask into the run.
void restore_run(Checkpoint& c, Body& body, State& state);

}  // namespace peridot

namespace peridot {

namespace {

const std::string point_offsets = "point_offsets";

std::string scheme_name(ExplicitScheme s) { return s == ExplicitScheme::central_difference ? "central_difference" : "velocity_verlet"; }

// Bond states a checkpoint holds: one per directed bond of a list, one per (point, offset) of a
// stencil (point_offsets), or in a checkpoint written before that, one per slot of the
// stencil's padded grid.
std::size_t bond_slots(const Body& body, const std::string& layout = point_offsets) {
  if (body.on_stencil() && layout == point_offsets) return body.size() * body.stencil.offsets();
  return body.bond_states().size();
}

}  // namespace

Checkpoint make_checkpoint(const Problem& p, const Setup& s, const State& state, double external_work, std::size_t broken) {
  Checkpoint c;
  c.deck_name = p.name;
  c.deck_hash = p.content_hash;
  c.dim = s.body.dim();
  c.points = s.body.size();
  c.bonds = bond_slots(s.body);
  c.bond_layout = s.body.on_stencil() ? point_offsets : "";
  c.dt = s.time_step.dt;
  c.scheme = scheme_name(p.solver.scheme);
  c.step = state.step;
  c.time = state.time;
  c.u = state.u;
  c.v = state.v;
  c.f = state.f;
  s.body.visit_bonds(overloaded{[&](const Stencil& st) {
                                  c.bond_state.resize(c.bonds);
                                  for (std::size_t i = 0, K = st.offsets(); i < s.body.size(); ++i)
                                    for (std::size_t k = 0; k < K; ++k) c.bond_state[i * K + k] = st.state[st.state_index(i, k)];
                                },
                                [&](const BondList& bl) { c.bond_state.assign(bl.intact.begin(), bl.intact.end()); }});
  c.external_work = external_work;
  c.broken = broken;
  return c;
}

namespace {

// What identifies the run a checkpoint belongs to: deck, sizes (points and bond states of the
// whole body), dimension, scheme, dt, content hash, and a step within the run.
void check_identity(const Checkpoint& c, const std::filesystem::path& file, const Problem& p, const Setup& s, std::uint64_t points,
                    std::uint64_t bonds) {
  const auto fail = [&](const std::string& what) { throw DeckError(fmt::format("restart {}: {}", file.string(), what)); };
  if (c.deck_name != p.name || c.points != points)
    fail(fmt::format("checkpoint is from deck '{}' with {} points; this deck '{}' has {} points", c.deck_name, c.points, p.name, points));
  if (c.dim != s.body.dim()) fail(fmt::format("checkpoint is {}D; this deck is {}D", c.dim, s.body.dim()));
  if (c.bonds != bonds)
    fail(fmt::format("checkpoint has {} bond states; this deck has {} (same {} points: horizon, quadrature, cracks or discretization.bonds "
                     "differ)",
                     c.bonds, bonds, c.points));
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
}

// Fracture only ever breaks bonds: one the deck's pre-cracks cut can't be intact again.
// `fresh` are the deck's own states of the same bonds; `at` names a state by its index.
template <class Name>
void check_list_states(std::span<const std::uint8_t> states, std::span<const std::uint8_t> fresh, const std::filesystem::path& file, Name at) {
  const auto fail = [&](const std::string& what) { throw DeckError(fmt::format("restart {}: {}", file.string(), what)); };
  for (std::size_t b = 0; b < states.size(); ++b) {
    if (states[b] > 1) fail(fmt::format("{} = {}; a bond is 0 (broken) or 1 (intact)", at(b), int(states[b])));
    if (states[b] > fresh[b]) fail(fmt::format("{} is intact, but this deck's pre-cracks cut that bond (geometry.cracks differ?)", at(b)));
  }
}

// A stencil's states carry an `exists` bit that fracture never changes: it must match this
// deck's, and a bond can be intact only where the deck's is.
template <class Name>
void check_stencil_state(std::uint8_t b, std::uint8_t fresh, const std::filesystem::path& file, Name at) {
  if (b > 3 || (b & Stencil::exists) != (fresh & Stencil::exists) || (b & Stencil::intact) > (fresh & Stencil::intact))
    throw DeckError(fmt::format("restart {}: {} = {} does not fit this deck's stencil (state {})", file.string(), at(), int(b), int(fresh)));
}

}  // namespace

// The box of a part's owned points' reference positions (lo x, y, z, hi x, y, z), as checkpoint
// parts record it.
std::array<double, 6> owned_box(const Setup& part) {
  std::array<double, 6> box{};
  box.fill(std::numeric_limits<double>::infinity());
  for (std::size_t k = 3; k < 6; ++k) box[k] = -box[k];
  for (auto j : part.slab.owned)
    for (std::size_t k = 0; k < 3; ++k) {
      const double x = part.body.points.x[k][std::size_t(j)];
      box[k] = std::min(box[k], x);
      box[k + 3] = std::max(box[k + 3], x);
    }
  return box;
}

Checkpoint read_restart(const std::filesystem::path& file, const Problem& p, const Setup& s) {
  Checkpoint c;
  try {
    c = read_checkpoint(file);
  } catch (const std::runtime_error& e) {
    throw DeckError(fmt::format("restart: {}", e.what()));
  }
  check_identity(c, file, p, s, s.body.size(), bond_slots(s.body, c.bond_layout));
  s.body.visit_bonds(overloaded{
      [&](const Stencil& st) {
        if (c.bond_layout == point_offsets) {
          for (std::size_t i = 0, K = st.offsets(); i < s.body.size(); ++i)
            for (std::size_t k = 0; k < K; ++k)
              check_stencil_state(c.bond_state[i * K + k], st.state[st.state_index(i, k)], file, [&] { return fmt::format("bond_state[{}]", i * K + k); });
        } else {
          for (std::size_t b = 0; b < c.bond_state.size(); ++b)
            check_stencil_state(c.bond_state[b], st.state[b], file, [&] { return fmt::format("bond_state[{}]", b); });
        }
      },
      [&](const BondList& bl) {
        check_list_states(c.bond_state, std::span<const std::uint8_t>(bl.intact.data(), bl.intact.size()), file,
                          [](std::size_t b) { return fmt::format("bond_state[{}]", b); });
      }});
  return c;
}

Checkpoint read_restart_part(const std::filesystem::path& file, const Problem& p, const Setup& part) {
  const Slab& slab = part.slab;
  std::vector<std::int64_t> ids;
  ids.reserve(slab.owned_size());
  for (auto j : slab.owned) ids.push_back(slab.local_ids[std::size_t(j)]);
  const bool stencil = part.body.on_stencil();
  const std::size_t K = stencil ? part.body.stencil.offsets() : 0;
  // What the checkpoint belongs to first, from its attributes: the parts this rank skips are
  // chosen by position, which only the same deck makes meaningful.
  Checkpoint c;
  int parts = 0;
  try {
    c = read_checkpoint_attributes(file, parts);
  } catch (const std::runtime_error& e) {
    throw DeckError(fmt::format("restart: {}", e.what()));
  }
  if (stencil != (c.bond_layout == point_offsets))
    throw DeckError(fmt::format("restart {}: the checkpoint holds the bonds of a {}; this deck runs on a {}", file.string(),
                                c.bond_layout == point_offsets ? "lattice stencil" : "bond list", stencil ? "lattice stencil" : "bond list"));
  check_identity(c, file, p, part, slab.global_size, stencil ? slab.global_size * K : slab.bond_starts.empty() ? 0 : slab.bond_starts.back());
  // A whole (one-file) checkpoint holds no row lengths: they are the deck's, and every row's
  // start comes from a sum over the ranks' blocks of ids (parallel::row_starts, collective).
  std::vector<std::uint64_t> lengths, starts;
  if (parts == 0) {
    for (auto j : slab.owned) lengths.push_back(stencil ? K : part.body.bonds.count(std::size_t(j)));
    starts = parallel::row_starts(ids, lengths, slab.global_size);
  }
  try {
    c = parts > 0 ? read_checkpoint_points(file, ids, owned_box(part)) : read_whole_checkpoint_points(file, ids, starts, lengths);
  } catch (const std::runtime_error& e) {
    throw DeckError(fmt::format("restart: {}", e.what()));
  }
  // Row by row: the owned rows are the whole body's, so each must have the deck's length.
  std::size_t at = 0;
  for (std::size_t q = 0; q < ids.size(); ++q) {
    const auto i = std::size_t(slab.owned[q]);
    const std::size_t count = stencil ? K : part.body.bonds.count(i);
    if (c.row_bonds[q] != count)
      throw DeckError(fmt::format("restart {}: point {} has {} bonds in the checkpoint; this deck gives it {} (horizon, quadrature or "
                                  "discretization differ)",
                                  file.string(), ids[q], c.row_bonds[q], count));
    part.body.visit_bonds(overloaded{[&](const Stencil& st) {
                                       for (std::size_t k = 0; k < K; ++k)
                                         check_stencil_state(c.bond_state[at + k], st.state[st.state_index(i, k)], file,
                                                             [&] { return fmt::format("offset {} of point {}", k, ids[q]); });
                                     },
                                     [&](const BondList& bl) {
                                       check_list_states(std::span<const std::uint8_t>(c.bond_state.data() + at, count),
                                                         std::span<const std::uint8_t>(bl.intact.data() + bl.begin(i), count), file,
                                                         [&](std::size_t b) { return fmt::format("bond {} of point {}", b, ids[q]); });
                                     }});
    at += count;
  }
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
  if (c.bond_state.size() != bond_slots(body, c.bond_layout))
    throw std::logic_error(fmt::format("restore_run: {} bond states for a body of {} (read_restart checks this)", c.bond_state.size(),
                                       bond_slots(body, c.bond_layout)));
  body.visit_bonds(overloaded{[&](Stencil& st) {
                                if (c.bond_layout != point_offsets) return void(std::copy(c.bond_state.begin(), c.bond_state.end(), st.state.begin()));
                                for (std::size_t i = 0, K = st.offsets(); i < body.size(); ++i)
                                  for (std::size_t k = 0; k < K; ++k) st.state[st.state_index(i, k)] = c.bond_state[i * K + k];
                              },
                              [&](BondList& bl) { std::copy(c.bond_state.begin(), c.bond_state.end(), bl.intact.begin()); }});
}

}  // namespace peridot
