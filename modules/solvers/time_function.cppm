export module peridot.solvers:time_function;
import peridot.std;

export namespace peridot {

// Dimensionless load history g(t) that scales a boundary value.
struct TimeFunction {
  enum class Kind { constant, ramp, exp_decay, table, sine };
  Kind kind = Kind::constant;
  double t0 = 0, t1 = 0;             // ramp: 0 before t0, 1 after t1 [s]
  double tau = 1;                    // exp_decay: g = exp(-t / tau) [s]
  std::vector<double> times, values; // table: piecewise linear, held constant outside
  double frequency = 1, phase = 0;   // sine: g = sin(2 pi frequency t + phase) [Hz, rad]

  static TimeFunction constant() { return {}; }
  static TimeFunction ramp(double t0, double t1) {
    if (!(t1 > t0)) throw std::invalid_argument("ramp: need t1 > t0");
    TimeFunction f;
    f.kind = Kind::ramp;
    f.t0 = t0;
    f.t1 = t1;
    return f;
  }
  static TimeFunction exp_decay(double tau) {
    if (!(tau > 0)) throw std::invalid_argument("exp_decay: need tau > 0");
    TimeFunction f;
    f.kind = Kind::exp_decay;
    f.tau = tau;
    return f;
  }
  static TimeFunction sine(double frequency, double phase = 0) {
    if (!(frequency > 0) || !std::isfinite(frequency)) throw std::invalid_argument("sine: need a finite frequency > 0");
    TimeFunction f;
    f.kind = Kind::sine;
    f.frequency = frequency;
    f.phase = phase;
    return f;
  }
  static TimeFunction table(std::vector<double> t, std::vector<double> v) {
    if (t.empty() || t.size() != v.size()) throw std::invalid_argument("table: times and values need equal, non-zero length");
    if (!std::is_sorted(t.begin(), t.end()) || std::adjacent_find(t.begin(), t.end()) != t.end())
      throw std::invalid_argument("table: times must be strictly increasing");
    TimeFunction f;
    f.kind = Kind::table;
    f.times = std::move(t);
    f.values = std::move(v);
    return f;
  }

  double operator()(double t) const {
    switch (kind) {
      case Kind::constant: return 1.0;
      case Kind::ramp: return std::clamp((t - t0) / (t1 - t0), 0.0, 1.0);
      case Kind::exp_decay: return std::exp(-t / tau);
      case Kind::sine: return std::sin(2 * std::numbers::pi * frequency * t + phase);
      case Kind::table: {
        if (t <= times.front()) return values.front();
        if (t >= times.back()) return values.back();
        const auto k = std::size_t(std::upper_bound(times.begin(), times.end(), t) - times.begin());
        const double a = (t - times[k - 1]) / (times[k] - times[k - 1]);
        return values[k - 1] + a * (values[k] - values[k - 1]);
      }
    }
    return 1.0;
  }
};

}  // namespace peridot
