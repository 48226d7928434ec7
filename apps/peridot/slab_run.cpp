#include <unistd.h>

#include <algorithm>
#include <array>
#include <functional>
#include <optional>
#include <variant>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <span>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>
#include <fmt/core.h>

#include "observers.hpp"
#include "progress.hpp"
#include "restart.hpp"
#include "slab_run.hpp"

using namespace peridot;

namespace {

// Copies the bond states of points ids[0..count) (point-major, K per point) between a stencil and
// a buffer: into the buffer when `pack`, out of it otherwise.
void copy_states(Stencil& st, const std::int64_t* ids, std::size_t count, std::uint8_t* buffer, bool pack) {
  const std::size_t K = st.offsets(), stride = st.row_length();
#pragma omp parallel for schedule(static)
  for (std::int64_t j = 0; j < std::int64_t(count); ++j) {
    std::uint8_t* at = st.state.data() + st.state_base(std::size_t(ids[j]));
    std::uint8_t* b = buffer + std::size_t(j) * K;
    for (std::size_t k = 0; k < K; ++k)
      if (pack) b[k] = at[k * stride];
      else at[k * stride] = b[k];
  }
}

// The same for a bond list: the rows of points ids[0..count), one after another.
void copy_states(BondList& bl, const std::int64_t* ids, std::size_t count, std::uint8_t* buffer, bool pack) {
  std::size_t at = 0;
  for (std::size_t j = 0; j < count; ++j) {
    const auto i = std::size_t(ids[j]);
    std::uint8_t* row = bl.intact.data() + bl.begin(i);
    if (pack) std::copy(row, row + bl.count(i), buffer + at);
    else std::copy(buffer + at, buffer + at + bl.count(i), row);
    at += bl.count(i);
  }
}

void copy_states(Body& body, const std::int64_t* ids, std::size_t count, std::uint8_t* buffer, bool pack) {
  if (body.on_stencil()) copy_states(body.stencil, ids, count, buffer, pack);
  else copy_states(body.bonds, ids, count, buffer, pack);
}

std::size_t broken_directed(const Body& body) { return body.on_stencil() ? body.stencil.broken() : body.bonds.broken(); }

// After a restart has scattered the owned rows' bond states: the ghosts whose rows a rank holds
// (state-based models) take their owners' rows, as fixed-width records through the halo.
void refresh_ghost_rows(const parallel::Halo& halo, const Slab& slab, BondList& bl) {
  std::size_t width = 0;
  for (std::size_t i = 0; i < slab.full_row.size(); ++i) width = std::max(width, bl.count(i));
  width = std::size_t(parallel::max_over_ranks(int(width)));
  std::vector<std::uint8_t> records(slab.local_size() * width, 0);
  for (std::size_t i = 0; i < slab.local_size(); ++i)
    std::copy(bl.intact.data() + bl.begin(i), bl.intact.data() + bl.end(i), records.data() + i * width);
  halo.exchange_records(records, width);
  for (auto g : slab.ghost) {
    const auto i = std::size_t(g);
    std::copy(records.data() + i * width, records.data() + i * width + bl.count(i), bl.intact.data() + bl.begin(i));
  }
}

// Moves owned fields and bond states between a rank's part and rank 0's whole body: each rank
// packs its owned points in order, rank 0 receives them rank after rank (Slab::gather_ids).
// Bond states travel point-major: on a stencil [point][offset] (the two stencils share their
// offsets), on a list the owned rows one after another (a rank's rows are the whole body's).
class Transfer {
 public:
  Transfer(const Slab& slab, Body& local, Body* whole) : slab_(slab), local_(local), whole_(whole) {
    if (local.on_stencil())
      for (auto s : slab.owned_starts) state_starts_.push_back(s * local.stencil.offsets());
    else state_starts_ = slab.bond_starts;
    const auto r = std::size_t(slab.rank);
    mine_.resize(slab.owned_size());
    bits_.resize(state_starts_[r + 1] - state_starts_[r]);
    if (whole_) {
      all_.resize(slab.global_size);
      all_bits_.resize(state_starts_.back());
    }
  }

  void gather(const State& s, State* w) {
    for (int c = 0; c < 3; ++c) {
      gather_field(s.u[c], w ? &w->u[c] : nullptr);
      gather_field(s.v[c], w ? &w->v[c] : nullptr);
      gather_field(s.f[c], w ? &w->f[c] : nullptr);
    }
    copy_states(local_, slab_.owned.data(), slab_.owned.size(), bits_.data(), true);
    parallel::gather_to_root(bits_, all_bits_, state_starts_);
    if (!whole_) return;
    copy_states(*whole_, slab_.gather_ids.data(), slab_.gather_ids.size(), all_bits_.data(), false);
    w->time = s.time;
    w->step = s.step;
  }

  // The inverse, for a restart: owned u, v, f and bond states from rank 0's whole run.
  void scatter(const State* w, State& s) {
    for (int c = 0; c < 3; ++c) {
      scatter_field(w ? &w->u[c] : nullptr, s.u[c]);
      scatter_field(w ? &w->v[c] : nullptr, s.v[c]);
      scatter_field(w ? &w->f[c] : nullptr, s.f[c]);
    }
    if (whole_) copy_states(*whole_, slab_.gather_ids.data(), slab_.gather_ids.size(), all_bits_.data(), true);
    parallel::scatter_from_root(all_bits_, bits_, state_starts_);
    copy_states(local_, slab_.owned.data(), slab_.owned.size(), bits_.data(), false);
    // Step and time from rank 0: the others contribute zeros.
    s.time = parallel::sum_over_ranks(w ? w->time : 0.0);
    s.step = std::size_t(parallel::sum_over_ranks(w ? double(w->step) : 0.0));
  }

 private:
  void gather_field(const std::vector<double>& local, std::vector<double>* whole) {
    for (std::size_t j = 0; j < mine_.size(); ++j) mine_[j] = local[std::size_t(slab_.owned[j])];
    parallel::gather_to_root(mine_, all_, slab_.owned_starts);
    if (whole)
      for (std::size_t j = 0; j < all_.size(); ++j) (*whole)[std::size_t(slab_.gather_ids[j])] = all_[j];
  }
  void scatter_field(const std::vector<double>* whole, std::vector<double>& local) {
    if (whole)
      for (std::size_t j = 0; j < all_.size(); ++j) all_[j] = (*whole)[std::size_t(slab_.gather_ids[j])];
    parallel::scatter_from_root(all_, mine_, slab_.owned_starts);
    for (std::size_t j = 0; j < mine_.size(); ++j) local[std::size_t(slab_.owned[j])] = mine_[j];
  }

  const Slab& slab_;
  Body& local_;
  Body* whole_;
  std::vector<std::size_t> state_starts_;
  std::vector<double> mine_, all_;
  std::vector<std::uint8_t> bits_, all_bits_;
};

}  // namespace

template <ForceModel Model>
int run_slab(const Problem& p, Setup& local, Setup* whole, const RunArgs& args, std::optional<Checkpoint>& restart) {
  const Slab& slab = local.slab;
  const bool root = slab.rank == 0;
  if (root != (whole != nullptr)) throw std::logic_error("simulate_slab: rank 0, and only rank 0, holds the whole set-up");
  const auto dir = std::filesystem::path(args.out_dir ? *args.out_dir : p.output.directory.string());
  // Each phase before the loop ends every rank when one rank fails in it (parallel::together
  // for rank-local work, or_abort where the phase holds collectives). The output directory is
  // made by rank 0's observers, after its DDS participant started and before any rank writes.
  const Model& model = std::get<Model>(local.model);
  const auto& o = p.output;

  State state(local.body.size());
  std::optional<State> all;
  std::optional<Transfer> transfer_holder;
  parallel::together("allocation", [&] {
    if (root) all.emplace(whole->body.size());
    transfer_holder.emplace(slab, local.body, root ? &whole->body : nullptr);
  });
  Transfer& transfer = *transfer_holder;
  const parallel::Halo halo = parallel::or_abort(
      "halo set-up", [&] { return parallel::Halo(slab.local_size(), slab.ghost, slab.ghost_owner, slab.ghost_owner_index); });
  const auto exchange = [&halo](VectorField& u) {
    const std::array<double*, 3> a{u[0].data(), u[1].data(), u[2].data()};
    halo.exchange(a);
  };
  // Broken bonds since t = 0, from the whole body's states: a bond across two slabs breaks on both.
  const std::size_t broken_at_start = root ? broken_directed(whole->body) : 0;
  typename ExplicitSolver<Model>::Counters counters;
  const bool restarting = parallel::max_over_ranks(restart ? 1 : 0) != 0;
  if (restarting) {
    parallel::together("restart", [&] {
      if (root) {
        counters = {restart->external_work, 0};
        restore_run(*restart, whole->body, *all);
        restart.reset();
      }
    }, is_input_error);
    parallel::or_abort("restart scatter", [&] {
      transfer.scatter(root ? &*all : nullptr, state);
      exchange(state.u);
      if (!local.body.on_stencil()) refresh_ghost_rows(halo, slab, local.body.bonds);
    });
    // A model that caches data of the bond mask (LPS) rebuilds it from the restored mask.
    if constexpr (requires { model.prepare(local.body); }) model.prepare(local.body);
  }
  const std::size_t first_step = state.step;
  ExplicitSolver<Model> solver(local.body, model, local.boundaries, local.time_step, p.solver.scheme);
  solver.set_exchange(exchange);
  // initialize computes the first forces, through the halo.
  parallel::or_abort("initial forces", [&] {
    if (first_step > 0) solver.restore(state, counters);
    else solver.initialize(state);
  });

  // Rank 0's observers, without the VTU (written here, piece by piece).
  Problem reporting = p;
  reporting.output.vtu_every = 0;
  std::optional<Observers> observers;
  const Model* whole_model = root ? &std::get<Model>(whole->model) : nullptr;
  parallel::together("observers and output directory", [&] {
    if (!root) return;
    // As in the one-rank run: a model's own damage measure, and the stress where it has pair forces.
    Observers::DamageFunction damage_of;
    if constexpr (requires(std::vector<double>& d) { whole_model->damage(whole->body, all->u, d); })
      damage_of = [&](const VectorField& u, std::vector<double>& d) { whole_model->damage(whole->body, u, d); };
    Observers::StressFunction stress_of;
    if constexpr (PairForceModel<Model>)
      if (!whole->body.on_stencil())
        stress_of = [&](const VectorField& u, StressField& tau) { tau = stress_field(*whole_model, whole->body, u); };
    observers.emplace(reporting, whole->body, dir, live_options(args, p.name),
                      std::move(damage_of), std::move(stress_of), first_step);
  });
  PvdSeries vtu(dir, p.name);
  if (first_step && o.vtu_every) vtu.resume(first_step);
  const PointCloud owned_points = subset(local.body.points, slab.owned);
  std::vector<double> phi, ids(slab.owned_size());
  for (std::size_t j = 0; j < ids.size(); ++j) ids[j] = double(slab.local_ids[std::size_t(slab.owned[j])]);
  std::array<std::vector<double>, 10> piece;  // u, v, f and damage at the owned points
  std::size_t vtu_steps = 0;

  Progress progress(local.time_step.steps, root && !args.quiet, first_step);
  const auto t0 = std::chrono::steady_clock::now();
  const auto wall = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(); };
  std::size_t broken = 0;
  double work = 0;
  const auto strain = [&] { return whole_model->strain_energy(whole->body, all->u); };

  // initial: the state before the first step, which observers report and checkpoints skip.
  const auto report = [&](bool last, bool initial) {
    const std::size_t n = state.step;
    const bool checkpoint = !initial && Observers::due(o.checkpoint_every, n, last);
    const bool gathered = Observers::due_at(o, n, last) || checkpoint;
    if (gathered) {
      transfer.gather(state, root ? &*all : nullptr);
      work = parallel::sum_over_ranks(solver.external_work());
      if (root) broken = (broken_directed(whole->body) - broken_at_start) / 2;
      // Rank 0's model reports from the gathered mask: one that caches data of it follows.
      if constexpr (requires { whole_model->prepare(whole->body); })
        if (root) whole_model->prepare(whole->body);
    }
    if (Observers::due(o.vtu_every, n, last)) {
      if constexpr (requires { model.damage(local.body, state.u, phi); }) solver.model().damage(local.body, state.u, phi);
      else damage(local.body, phi);
      const std::vector<double>* from[10] = {&state.u[0], &state.u[1], &state.u[2], &state.v[0], &state.v[1],
                                             &state.v[2], &state.f[0], &state.f[1], &state.f[2], &phi};
      for (std::size_t q = 0; q < piece.size(); ++q) {
        piece[q].resize(slab.owned_size());
        for (std::size_t j = 0; j < slab.owned_size(); ++j) piece[q][j] = (*from[q])[std::size_t(slab.owned[j])];
      }
      const NamedField fields[] = {
          {"displacement", 3, {piece[0], piece[1], piece[2]}},
          {"velocity", 3, {piece[3], piece[4], piece[5]}},
          {"force", 3, {piece[6], piece[7], piece[8]}},
          {"damage", 1, {piece[9], {}, {}}},
          {"global_id", 1, {ids, {}, {}}},
      };
      vtu.write_piece(n, slab.rank, owned_points, fields);
      parallel::barrier();  // every piece exists before the .pvtu names it
      if (root) vtu.add_pieces(state.time, n, slab.ranks, fields);
      ++vtu_steps;
    }
    if (root && Observers::due_at(o, n, last)) observers->observe(*all, work, broken, strain, last, wall());
    if (root && checkpoint) {
      const auto file = dir / o.checkpoint_file;
      write_checkpoint(file, make_checkpoint(p, *whole, *all, work, broken));
      if (!args.quiet) {
        progress.clear();
        fmt::print("  checkpoint: step {}, t = {:.4e} s -> {}\n", n, state.time, file.string());
      }
    }
  };

  try {
    report(first_step == local.time_step.steps, true);
    for (std::size_t k = first_step; k < local.time_step.steps; ++k) {
      parallel::inject_failure("stepping");
      solver.step(state);
      report(k + 1 == local.time_step.steps, false);
      if (root) progress.update(state.step, state.time, broken);
    }
  } catch (const std::exception& e) {
    // The other ranks wait in the next collective: end them all.
    progress.finish();
    if (observers) observers->finish(false, e.what());
    parallel::abort_from("stepping", e);
  }
  progress.finish();
  if (!root) return exit_ok;
  observers->finish(true, "");
  if (!args.quiet) {
    std::size_t least = SIZE_MAX, most = 0;
    for (int r = 0; r < slab.ranks; ++r) {
      const std::size_t m = slab.owned_starts[std::size_t(r) + 1] - slab.owned_starts[std::size_t(r)];
      least = std::min(least, m);
      most = std::max(most, m);
    }
    const std::string cut = slab.axis >= 0 ? fmt::format("slabs across {}", "xyz"[slab.axis]) : "coordinate bisection";
    std::string extra =
        fmt::format("  MPI: {} ranks, {} of {} to {} points, {} ghost points on rank 0", slab.ranks, cut, least, most, halo.ghosts());
    if (vtu_steps) extra += fmt::format("\n  output: {} ({} steps, one piece per rank)", vtu.pvd().string(), vtu_steps);
    observers->print_done(*all, wall(), broken, extra);
  }
  return exit_ok;
}

int simulate_slab(const Problem& p, Setup& local, Setup* whole, const RunArgs& args, std::optional<Checkpoint>& restart) {
  return std::visit(
      [&](const auto& m) -> int {
        return run_slab<std::decay_t<decltype(m)>>(p, local, whole, args, restart);
      },
      local.model);
}
