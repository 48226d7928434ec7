module;
#include <peridot/run_record.hpp>
export module peridot.observe:observers;
import peridot.std;
import peridot.problem;
import peridot.analysis;
import peridot.live;
import peridot.render;
import :sample;

export namespace peridot {

// The von Mises stress sqrt(3 J2) of tau at each point; in 2D (zz, yz, xz empty) the
// plane-stress reading.
void von_mises(const StressField& tau, std::vector<double>& out);

// How the deck's PNG snapshots are drawn (output.png): width, deformation, 3D view.
RenderOptions png_options(const OutputSpec& o);
// The colour values of the PNG fields "displacement" (|u| [m]) and "velocity" (|v| [m/s]) at
// each point into `out`; returns the colorbar's label.
std::string png_magnitudes(const std::string& field, const std::array<std::span<const double>, 3>& u,
                           const std::array<std::span<const double>, 3>& v, std::vector<double>& out);
// Whether a PNG field is drawn from the stress tensor (stress_xx, _yy, _xy, von_mises).
bool stress_png(const std::string& field);
// The colour values of such a field from tau (von gets the von Mises stress), and the colorbar's label.
std::span<const double> stress_png_values(const std::string& field, const StressField& tau, std::vector<double>& von, std::string& label);
// tau's components as the VTU's separate scalars (stress_xx, ... as the PNG fields are named).
void add_stress_fields(std::vector<NamedField>& fields, const StressField& tau, int dim);

// Everything a run reports while it goes: VTU/PVD, CSV history, PNG snapshots, live DDS
// state, fragment counts, crack-tip tracking and user observers, each on its own cadence
// (deck `output`). Called once per step; does work only on steps where some observer is due.
class Observers {
 public:
  // damage_of: a model's own damage field (RNP: max |S| / S_c); empty: broken-bond damage.
  using DamageFunction = std::function<void(const VectorField& u, std::vector<double>& phi)>;
  // stress_of: the peridynamic stress tau of the run's model at u (stress_field); empty when
  // the model has no pair forces, and then no output may ask for the stress.
  using StressFunction = std::function<void(const VectorField& u, StressField& tau)>;
  // resume_step > 0: a run restarted from a checkpoint at that step. The CSV history keeps its
  // rows before the step and the .pvd its earlier files; crack-tip and fragment tracking start
  // afresh from the restart.
  // The DDS participant starts first: when it cannot, the run fails before any file or
  // directory exists. Then the output directory is made.
  Observers(const Problem& problem, const Body& body, const std::filesystem::path& dir, LiveOptions live, DamageFunction damage_of = {},
            StressFunction stress_of = {}, std::size_t resume_step = 0);
  // The deck key that asks for the stress ("output.vtu.stress = true", a stress output.png.field),
  // or "" when no output needs it.
  static std::string stress_request(const OutputSpec& o);
  // Whether an output of cadence `every` (0: off) reports at this step.
  static bool due(std::size_t every, std::size_t step, bool last) { return every > 0 && (step % every == 0 || last); }
  // Whether any built-in observer of `o` reports at this step.
  static bool due_at(const OutputSpec& o, std::size_t step, bool last);
  // Whether any observer of this run, user observers included, reports at this step.
  bool due_now(std::size_t step, bool last) const;
  void add(AnyObserver o) { users_.push_back(std::move(o)); }
  // A part observer's cadence: the history row it reads on rank 0 is made on its steps too.
  void add_cadence(std::size_t every) { cadences_.push_back(every); }
  // What the record's time is for the history plot's x axis: "time [s]", or "load factor".
  void set_abscissa(std::string label) { abscissa_ = time_label_ = std::move(label); }
  // Figures a distributed stepper reduces over its ranks, so that rank 0 needs no whole field
  // for the history row.
  // Some points of the body with their damage, gathered from the ranks in global order.
  struct Points {
    PointCloud points;
    std::vector<double> damage;
  };
  struct Totals {
    double kinetic_energy = 0, damage_fraction = 0;
    std::optional<FragmentReport> fragments;  // joined from the ranks' shares on the steps fragments are due
    // The cracked points (damage at least the trackers' thresholds) for crack tips and
    // fronts, with the body's extent along the front's axis; null: the whole body's.
    const Points* cracked = nullptr;
    std::array<double, 2> front_extent{0, 0};
    // A DDS snapshot's points already decimated (every stride-th of the body's points), at
    // deformed positions; null: the whole body's.
    const Points* snapshot = nullptr;
    std::size_t points = 0;  // the body's
  };
  // totals: given, the row takes them instead of summing the state's fields.
  void observe(const State& state, double external_work, std::size_t broken, const std::function<double()>& strain, bool last, double wall,
               const Totals* totals = nullptr);
  // The end of the run: DDS publishes the final summary (FINISHED, or FAILED with the message),
  // user observers hear how it ended.
  void finish(const RunEnd& end);
  // An implicit solver's work in one step; rows report the sums since the previous row.
  void add_solver_work(long iterations, long sub_iterations) {
    iterations_ += iterations;
    sub_iterations_ += sub_iterations;
    implicit_ = true;
  }
  const RunRecord& last_row() const { return row_; }
  // Whether any row was observed: a run whose deck asks for no observer on its cadence (a static
  // run that writes only its own VTU) has none, and last_row() is then all zeros.
  bool observed() const { return observed_; }
  // The closing lines of a run: the observers' summaries and the files written.
  std::vector<std::string> summary() const;

 private:
  const Problem& p_;
  DamageFunction damage_of_;
  StressFunction stress_of_;
  const Body& body_;
  std::filesystem::path dir_;
  PvdSeries vtu_;
  std::unique_ptr<HistoryCsv> csv_;
  std::optional<CrackTipTracker> tips_;
  std::optional<CrackFrontTracker> fronts_;
  std::unique_ptr<RecordFile> front_csv_, front_points_csv_;
  std::unique_ptr<LivePublisher> live_;
  RunSummarySample summary_;  // reused, so publishing allocates nothing once warm
  std::optional<FragmentReport> fragments_;
  std::vector<AnyObserver> users_;
  std::vector<std::size_t> cadences_;
  std::vector<RunRecord> history_;  // rows for the history plot
  std::string abscissa_ = "time [s]";
  std::string time_label_;  // the PNG title's name for the record's time when it is not seconds
  std::filesystem::path plot_file_;
  void write_plot();
  std::vector<double> phi_, deformed_[3], von_mises_, magnitude_;
  StressField stress_;
  RunRecord row_;
  bool observed_ = false;
  std::size_t pngs_ = 0;
  std::size_t published_ = 0;
  double publish_seconds_ = 0;  // solver-thread time spent in LivePublisher calls
  std::filesystem::path last_png_;
  long iterations_ = 0, sub_iterations_ = 0;
  bool implicit_ = false;
};

}  // namespace peridot

namespace peridot {

bool stress_png(const std::string& field) { return field.starts_with("stress_") || field == "von_mises"; }

std::span<const double> stress_png_values(const std::string& field, const StressField& tau, std::vector<double>& von, std::string& label) {
  if (field == "von_mises") {
    von_mises(tau, von);
    label = "von Mises [Pa]";
    return von;
  }
  label = field + " [Pa]";
  return field == "stress_xx" ? tau.xx : field == "stress_yy" ? tau.yy : tau.xy;
}

void add_stress_fields(std::vector<NamedField>& fields, const StressField& tau, int dim) {
  // Separate scalars: ParaView lists each one to colour by, as the PNG fields are named.
  fields.push_back({"stress_xx", 1, {tau.xx, {}, {}}});
  if (dim >= 2) {
    fields.push_back({"stress_yy", 1, {tau.yy, {}, {}}});
    fields.push_back({"stress_xy", 1, {tau.xy, {}, {}}});
  }
  if (dim == 3) {
    fields.push_back({"stress_zz", 1, {tau.zz, {}, {}}});
    fields.push_back({"stress_yz", 1, {tau.yz, {}, {}}});
    fields.push_back({"stress_xz", 1, {tau.xz, {}, {}}});
  }
}

// sqrt(J2 * 3) of tau; in 2D zz = yz = xz = 0, the plane-stress reading.
void von_mises(const StressField& t, std::vector<double>& out) {
  out.resize(t.size());
  const bool solid = !t.zz.empty();
  for (std::size_t i = 0; i < t.size(); ++i) {
    const double xx = t.xx[i], yy = t.yy[i], xy = t.xy[i];
    const double zz = solid ? t.zz[i] : 0.0, yz = solid ? t.yz[i] : 0.0, xz = solid ? t.xz[i] : 0.0;
    out[i] = std::sqrt(0.5 * ((xx - yy) * (xx - yy) + (yy - zz) * (yy - zz) + (zz - xx) * (zz - xx)) + 3 * (xy * xy + yz * yz + xz * xz));
  }
}

RenderOptions png_options(const OutputSpec& o) {
  RenderOptions ro;
  ro.width = o.png_width;
  ro.deformed = o.png_deformed;
  ro.magnification = o.png_magnification;
  ro.view3d = o.png_projection ? RenderOptions::View3D::projection : RenderOptions::View3D::slice;
  ro.axis = o.png_axis;
  ro.slice_position = o.png_slice_at;
  return ro;
}

std::string png_magnitudes(const std::string& field, const std::array<std::span<const double>, 3>& u,
                           const std::array<std::span<const double>, 3>& v, std::vector<double>& out) {
  const auto& f = field == "displacement" ? u : v;
  out.resize(f[0].size());
  for (std::size_t i = 0; i < out.size(); ++i) out[i] = std::sqrt(f[0][i] * f[0][i] + f[1][i] * f[1][i] + f[2][i] * f[2][i]);
  return "|" + field + "| [" + (field == "velocity" ? "m/s" : "m") + "]";
}

std::string Observers::stress_request(const OutputSpec& o) {
  if (o.vtu_every && o.vtu_stress) return "output.vtu.stress = true";
  if (o.png_every && stress_png(o.png_field)) return fmt::format("output.png.field = '{}'", o.png_field);
  return {};
}

Observers::Observers(const Problem& p, const Body& body, const std::filesystem::path& dir, LiveOptions live, DamageFunction damage_of,
                     StressFunction stress_of, std::size_t resume_step)
    : p_(p), damage_of_(std::move(damage_of)), stress_of_(std::move(stress_of)), body_(body), dir_(dir), vtu_(dir, p.name) {
  const auto& o = p.output;
  if (const auto key = stress_request(o); !key.empty() && !stress_of_)
    throw std::invalid_argument(fmt::format("{}: this model reports no pair forces, so it has no stress tensor", key));
  if (o.dds_every || o.dds_snapshot_every) live_ = std::make_unique<LivePublisher>(live);
  if (o.csv_every || o.vtu_every || o.png_every || o.plot_every) std::filesystem::create_directories(dir);
  if (o.csv_every) csv_ = std::make_unique<HistoryCsv>(dir / (p.name + "_history.csv"), resume_step);
  if (resume_step && o.vtu_every) vtu_.resume(resume_step);
  if (o.crack_front_every) {  // the deck allows it in 3D only
    fronts_.emplace(CrackFrontOptions{.axis = o.crack_front_axis,
                                      .direction = o.crack_front_direction,
                                      .origin = o.crack_front_origin,
                                      .damage_threshold = o.crack_front_threshold});
    std::filesystem::create_directories(dir);
    front_csv_ = std::make_unique<RecordFile>(dir / (p.name + "_crack_front.csv"));
    front_csv_->append("step,time_s,cracked_slices,slices,length_m,mean_advance_m,max_advance_m,mean_speed_m_per_s,max_speed_m_per_s,branched_slices\n");
    // The front as points, a row per cracked slice and sample: the curve itself, for plotting.
    front_points_csv_ = std::make_unique<RecordFile>(dir / (p.name + "_crack_front_points.csv"));
    front_points_csv_->append("step,time_s,slice,x_m,y_m,z_m\n");
  }
  if (o.crack_tip_every) {  // the deck allows it in 2D only
    CrackTipOptions t;
    t.damage_threshold = o.crack_tip_threshold;
    t.origin = o.crack_tip_origin;
    t.direction = o.crack_tip_direction;
    t.speed_along_direction = o.crack_tip_speed_along_direction;
    tips_.emplace(t);
  }
}

bool Observers::due_at(const OutputSpec& o, std::size_t n, bool last) {
  return due(o.vtu_every, n, last) || due(o.csv_every, n, last) || due(o.plot_every, n, last) || due(o.png_every, n, last) || due(o.dds_every, n, last) ||
         due(o.dds_snapshot_every, n, last) || due(o.fragments_every, n, last) || due(o.crack_tip_every, n, last) || due(o.crack_front_every, n, last);
}

bool Observers::due_now(std::size_t n, bool last) const {
  return due_at(p_.output, n, last) || std::ranges::any_of(users_, [&](const AnyObserver& u) { return u.due(n, last); }) ||
         std::ranges::any_of(cadences_, [&](std::size_t every) { return due(every, n, last); });
}

void Observers::observe(const State& s, double external_work, std::size_t broken, const std::function<double()>& strain, bool last,
                        double wall, const Totals* totals) {
  const auto& o = p_.output;
  const std::size_t n = s.step;
  if (!due_now(n, last)) return;
  if (damage_of_) damage_of_(s.u, phi_);
  else damage(body_, phi_);
  row_ = RunRecord{};
  observed_ = true;
  row_.step = n;
  row_.time = s.time;
  row_.kinetic_energy = totals ? totals->kinetic_energy : kinetic_energy(body_, s.v);
  row_.strain_energy = strain();
  row_.external_work = external_work;
  row_.broken_bonds = broken;
  row_.damage_fraction = totals ? totals->damage_fraction : damage_fraction(body_, phi_);
  row_.wall_time = wall;
  if (!std::isfinite(row_.kinetic_energy) || !std::isfinite(row_.strain_energy))
    throw std::runtime_error(fmt::format("the solution diverged (non-finite energy) at step {}, t = {:.4e} s; reduce solver.dt", n, s.time));
  if (due(o.fragments_every, n, last)) {
    if (totals && totals->fragments) fragments_ = totals->fragments;
    else fragments_ = count_fragments(body_, {.large_mass_fraction = o.large_fragment_fraction});
  }
  if (fragments_) row_.fragments = long(fragments_->count);
  const Points* cracked = totals ? totals->cracked : nullptr;
  const PointCloud& crack_points = cracked ? cracked->points : body_.points;
  const std::span<const double> crack_damage = cracked ? std::span<const double>(cracked->damage) : phi_;
  if (tips_ && due(o.crack_tip_every, n, last)) tips_->update(crack_points, crack_damage, s.time);
  if (fronts_ && due(o.crack_front_every, n, last)) {
    const auto& f = fronts_->update(crack_points, crack_damage, s.time, cracked ? &totals->front_extent : nullptr);
    front_csv_->append(fmt::format("{},{:.9e},{},{},{:.6e},{:.6e},{:.6e},{:.6e},{:.6e},{}\n", n, s.time, f.cracked_slices, f.slices, f.length,
                                   f.mean_advance, f.max_advance, f.mean_speed, f.max_speed, f.branched_slices));
    std::string rows;
    for (std::size_t k = 0; k < f.front.size(); ++k)
      if (const auto& q = f.front[k]) rows += fmt::format("{},{:.9e},{},{:.9e},{:.9e},{:.9e}\n", n, s.time, k, (*q)[0], (*q)[1], (*q)[2]);
    front_points_csv_->append(rows);
  }
  if (fronts_)
    if (const auto& f = fronts_->last()) {
      row_.front_length = f->length;
      row_.front_mean_advance = f->mean_advance;
      row_.front_max_advance = f->max_advance;
      row_.front_max_speed = f->max_speed;
      row_.front_branched_slices = long(f->branched_slices);
    }
  if (tips_)
    if (const auto tip = tips_->current()) {
      row_.tip_x = tip->position[0];
      row_.tip_y = tip->position[1];
      row_.tip_speed = tip->speed;
    }
  if (implicit_) {
    row_.linear_iterations = iterations_;
    row_.sub_iterations = sub_iterations_;
  }
  if (due(o.plot_every, n, last) && (history_.empty() || history_.back().step != n)) history_.push_back(row_);
  if (csv_ && due(o.csv_every, n, last)) {
    csv_->append(row_);
    iterations_ = sub_iterations_ = 0;
  }
  const bool vtu_due = due(o.vtu_every, n, last), png_due = due(o.png_every, n, last);
  // A pair-force pass (and on a lattice a bond-crossing search): only on steps that write it.
  if ((vtu_due && o.vtu_stress) || (png_due && stress_png(o.png_field))) stress_of_(s.u, stress_);
  if (vtu_due) {
    std::vector<NamedField> fields{
        {"displacement", 3, {s.u[0], s.u[1], s.u[2]}},
        {"velocity", 3, {s.v[0], s.v[1], s.v[2]}},
        {"force", 3, {s.f[0], s.f[1], s.f[2]}},
        {"damage", 1, {phi_, {}, {}}},
    };
    if (o.vtu_stress) add_stress_fields(fields, stress_, body_.dim());
    vtu_.write(s.time, n, body_.points, fields);
  }
  if (png_due) {
    std::span<const double> values = phi_;
    std::string label = "damage";
    if (stress_png(o.png_field)) {
      values = stress_png_values(o.png_field, stress_, von_mises_, label);
    } else if (o.png_field != "damage") {
      label = png_magnitudes(o.png_field, {s.u[0], s.u[1], s.u[2]}, {s.v[0], s.v[1], s.v[2]}, magnitude_);
      values = magnitude_;
    }
    RenderField rf;
    rf.dim = body_.dim();
    rf.x = {body_.points.x[0], body_.points.x[1], body_.points.x[2]};
    rf.u = {s.u[0], s.u[1], s.u[2]};
    rf.values = values;
    rf.field_name = label;
    rf.time = s.time;
    rf.time_label = time_label_;
    rf.step = n;
    rf.spacing = body_.points.spacing;
    const RenderOptions ro = png_options(o);
    last_png_ = dir_ / fmt::format("{}_{:07d}.png", p_.name, n);
    render_png(last_png_, rf, ro);
    ++pngs_;
  }
  const auto publish_start = std::chrono::steady_clock::now();
  const std::size_t published_before = published_;
  if (live_ && due(o.dds_every, n, last)) {
    summary_.record = row_;
    summary_.status = RunStatus::running;
    summary_.front_points.clear();
    if (fronts_)
      if (const auto& f = fronts_->last())
        for (const auto& q : f->front)
          for (int c = 0; c < 3; ++c) summary_.front_points.push_back(q ? (*q)[c] : std::numeric_limits<double>::quiet_NaN());
    live_->publish_summary(summary_);
    ++published_;
  }
  if (live_ && due(o.dds_snapshot_every, n, last) && totals && totals->snapshot) {
    const auto& q = *totals->snapshot;
    live_->publish_snapshot(q.points.dim, q.points.x[0], q.points.x[1], q.points.dim == 3 ? std::span<const double>(q.points.x[2]) : std::span<const double>{},
                            q.damage, n, s.time, totals->points);
    ++published_;
  } else if (live_ && due(o.dds_snapshot_every, n, last)) {
    // Deformed positions, so a viewer sees the opening crack.
    for (int k = 0; k < 3; ++k) {
      deformed_[k].resize(body_.size());
      for (std::size_t i = 0; i < body_.size(); ++i) deformed_[k][i] = body_.points.x[k][i] + s.u[k][i];
    }
    live_->publish_snapshot(body_.dim(), deformed_[0], deformed_[1], body_.dim() == 3 ? std::span<const double>(deformed_[2]) : std::span<const double>{},
                            phi_, n, s.time);
    ++published_;
  }
  if (published_ != published_before)
    publish_seconds_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - publish_start).count();
  const Sample sample{body_, s, row_, last};
  for (const auto& u : users_)
    if (u.due(n, last)) u.observe(sample);
}

void Observers::finish(const RunEnd& end) {
  // The plot of what happened, also when the run failed or stopped: it shows how far it got.
  if (p_.output.plot_every && !history_.empty()) write_plot();
  if (live_) live_->finish(end.ok, end.message);
  for (const auto& u : users_) u.finish(end);
}

void Observers::write_plot() {
  std::vector<double> t, kinetic, strain, work, broken, damage, tip_x, tip_y, tip_speed;
  bool tips = false;
  for (const auto& r : history_) {
    t.push_back(r.time);
    kinetic.push_back(r.kinetic_energy), strain.push_back(r.strain_energy), work.push_back(r.external_work);
    broken.push_back(double(r.broken_bonds)), damage.push_back(r.damage_fraction);
    tip_x.push_back(r.tip_x), tip_y.push_back(r.tip_y), tip_speed.push_back(r.tip_speed);
    tips = tips || std::isfinite(r.tip_x);
  }
  std::vector<PlotPanel> panels{
      {"energy [J]", {{"kinetic", kinetic}, {"strain", strain}, {"external work", work}}},
      {"broken bonds", {{"broken bonds", broken}}},
      {"damage fraction", {{"damage fraction", damage}}},
  };
  if (tips) {
    panels.push_back({"crack tip [m]", {{"x", tip_x}, {"y", tip_y}}});
    panels.push_back({"crack tip speed [m/s]", {{"speed", tip_speed}}});
  }
  plot_file_ = dir_ / (p_.name + "_history.png");
  plot_png(plot_file_, t, panels, {.title = fmt::format("{}: history", p_.name), .x_label = abscissa_});
}

std::vector<std::string> Observers::summary() const {
  std::vector<std::string> out;
  if (fragments_)
    out.push_back(fmt::format("  fragments: {} ({} large above {:.3g} of the mass), {} debris points", fragments_->count, fragments_->large,
                              p_.output.large_fragment_fraction, fragments_->debris));
  if (tips_) {
    const auto t = tips_->summary();
    if (!t.initiated) out.push_back(fmt::format("  crack tip: no crack above damage {:.2f}", p_.output.crack_tip_threshold));
    else {
      out.push_back(fmt::format("  crack tip at ({:.4f}, {:.4f}) m; max speed {:.0f} m/s, mean {:.0f} m/s", t.tip[0], t.tip[1], t.max_speed,
                                t.mean_speed));
      if (t.branch)
        out.push_back(fmt::format("  branching at x = {:.4f} m, y = {:.4f} m, t = {:.2f} us", t.branch->position[0], t.branch->position[1],
                                  t.branch->time * 1e6));
    }
  }
  if (fronts_ && fronts_->last()) {
    const auto& f = *fronts_->last();
    out.push_back(fmt::format("  crack front: {} of {} slices cracked, length {:.4g} m, advance mean {:.4g} m, max {:.4g} m; max speed {:.0f} m/s",
                              f.cracked_slices, f.slices, f.length, f.mean_advance, f.max_advance, fronts_->max_speed()));
    if (const auto& b = f.first_branch)
      out.push_back(fmt::format("  crack front branched in {} of {} slices; first in slice {} at ({:.4f}, {:.4f}, {:.4f}) m, t = {:.2f} us",
                                f.branched_slices, f.slices, b->slice, b->position[0], b->position[1], b->position[2], b->time * 1e6));
    out.push_back(fmt::format("  output: {}", (dir_ / (p_.name + "_crack_front.csv")).string()));
    out.push_back(fmt::format("  output: {}", (dir_ / (p_.name + "_crack_front_points.csv")).string()));
  }
  if (p_.output.vtu_every) out.push_back(fmt::format("  output: {}", vtu_.pvd().string()));
  if (csv_) out.push_back(fmt::format("  output: {}", (dir_ / (p_.name + "_history.csv")).string()));
  if (!plot_file_.empty()) out.push_back(fmt::format("  output: {}", plot_file_.string()));
  if (pngs_) out.push_back(fmt::format("  output: {} PNG snapshots (last {})", pngs_, last_png_.string()));
  if (live_)
    out.push_back(fmt::format("  output: DDS run id '{}': {} samples, {:.1f} us of solver time per publish call", live_->run_id(), published_,
                              published_ ? 1e6 * publish_seconds_ / double(published_) : 0.0));
  return out;
}

}  // namespace peridot
