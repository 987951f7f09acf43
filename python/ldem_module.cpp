// The Python module's compiled part, ldem._core: a case's check, `ldem run` and `ldem resume`
// as functions, and a simulation stepped from Python with its state as numpy arrays. The
// package (python/ldem/__init__.py) wraps it: case objects, errors, readers of output folders.
#include "app/case_run.hpp"
#include "app/run_body.hpp"
#include "util/error.hpp"

#include <atomic>
#include <csignal>
#include <fmt/format.h>
#include <memory>
#include <omp.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <string>

namespace py = pybind11;

namespace ldem {
namespace {

// Python's SIGINT and SIGTERM handlers, put back when the scope ends whatever happens: a run
// installs its own (a Ctrl-C stops it with a checkpoint), and Simulation::step `handler`.
class KeepSignals {
public:
  explicit KeepSignals(void (*handler)(int) = nullptr) {
    sigaction(SIGINT, nullptr, &old_int_);
    sigaction(SIGTERM, nullptr, &old_term_);
    if (handler) {
      struct sigaction a {};
      a.sa_handler = handler;
      sigemptyset(&a.sa_mask);
      sigaction(SIGINT, &a, nullptr);
      sigaction(SIGTERM, &a, nullptr);
    }
  }
  ~KeepSignals() {
    sigaction(SIGINT, &old_int_, nullptr);
    sigaction(SIGTERM, &old_term_, nullptr);
  }
  KeepSignals(const KeepSignals&) = delete;
  KeepSignals& operator=(const KeepSignals&) = delete;

private:
  struct sigaction old_int_ {
  }, old_term_{};
};

std::atomic<int> g_stop{0};
void on_stop(int sig) {
  g_stop = sig;
}

// OpenMP's thread count when the module was loaded (OMP_NUM_THREADS, else the cores): what
// threads = 0 asks for.
int g_default_threads = 1;

void set_threads(int threads) {
  if (threads < 0)
    throw InputError(
        fmt::format("threads: expected 0 (OpenMP's default) or more, got {}", threads));
  omp_set_num_threads(threads > 0 ? threads : g_default_threads);
}

// Validates a case: parsed, its body's modules and node sets built (the simulation itself is
// built by run and Simulation).
void check_case(const std::string& name, const std::string& text) {
  build_case(name, nullptr, false, &text);
}

// `ldem run`: the exit code (0 done, 130 or 143 stopped by a signal with a checkpoint, 3 blown
// up). The run's own handlers take Ctrl-C, and Python's come back after it.
int run(const std::string& name, const std::optional<std::string>& text, const std::string& out,
        int threads, bool plots, bool force) {
  set_threads(threads);
  RunOptions o;
  o.out_dir = out;
  o.threads = threads;
  o.plots = plots;
  o.force = force;
  o.case_text = text;
  KeepSignals keep;
  py::gil_scoped_release release;
  return run_command(name, o);
}

int resume(const std::string& out, int threads, bool plots, std::optional<double> end) {
  set_threads(threads);
  KeepSignals keep;
  py::gil_scoped_release release;
  return resume_command(out, threads, plots, 0, 0, end);
}

// A case's body stepped from Python, in one process: the same RunBody as `ldem run` steps, so
// the same steps give the same numbers.
class PySimulation {
public:
  PySimulation(const std::string& name, const std::string& text, int threads) {
    set_threads(threads);
    case_ = std::make_unique<BuiltCase>(build_case(name, nullptr, true, &text));
    body_ = make_serial_body(*case_);
    body_->agree_on_body();
    for (const ProbeSpec& p : case_->spec.probes)
      probe_names_.push_back(p.name);
  }

  // n steps; the last one reports (energies and probes at its start). Stops between steps on
  // Ctrl-C (KeyboardInterrupt, the steps done kept).
  void step(std::uint64_t n) {
    int stopped = 0;
    {
      py::gil_scoped_release release;
      g_stop = 0;
      KeepSignals keep(on_stop);
      for (std::uint64_t i = 0; i < n; ++i) {
        if ((stopped = g_stop) != 0)
          break;
        body_->step(i + 1 == n);
      }
    }
    if (stopped) {
      PyErr_SetNone(PyExc_KeyboardInterrupt);
      throw py::error_already_set();
    }
  }

  double time() const { return body_->time(); }
  std::uint64_t step_count() const { return body_->step_count(); }
  double dt() const { return body_->dt(); }
  const Simulation& sim() const { return *case_->sim; }
  Simulation& sim() { return *case_->sim; }
  const Lattice& lattice() const { return sim().lattice(); }

  // Nodes x 3 of u_n (velocity: false) or v_{n-1/2}.
  py::array_t<double> node_vectors(bool velocity) const {
    const index_t n = lattice().num_nodes();
    py::array_t<double> a({static_cast<py::ssize_t>(n), py::ssize_t{3}});
    std::vector<Vec3> other(static_cast<std::size_t>(n));
    auto* data = reinterpret_cast<Vec3*>(a.mutable_data());
    static_assert(sizeof(Vec3) == 3 * sizeof(double));
    if (velocity)
      sim().node_states(0, n, other.data(), data);
    else
      sim().node_states(0, n, data, other.data());
    return a;
  }
  py::array_t<double> positions() const {
    const index_t n = lattice().num_nodes();
    py::array_t<double> a({static_cast<py::ssize_t>(n), py::ssize_t{3}});
    auto* data = reinterpret_cast<Vec3*>(a.mutable_data());
    for (index_t i = 0; i < n; ++i)
      data[i] = lattice().position(i);
    return a;
  }
  py::array_t<bool> node_present() const {
    const index_t n = lattice().num_nodes();
    py::array_t<bool> a(static_cast<py::ssize_t>(n));
    bool* d = a.mutable_data();
    for (index_t i = 0; i < n; ++i)
      d[i] = lattice().node_present(i);
    return a;
  }
  py::array_t<std::int64_t> bar_nodes() const {
    const index_t n = lattice().num_bars();
    py::array_t<std::int64_t> a({static_cast<py::ssize_t>(n), py::ssize_t{2}});
    std::int64_t* d = a.mutable_data();
    for (index_t b = 0; b < n; ++b) {
      const auto e = lattice().bar_nodes(b);
      d[2 * b] = e[0];
      d[2 * b + 1] = e[1];
    }
    return a;
  }
  // Per bar: state (0 intact, 1 softening, 2 broken), damage, axial force, axial strain.
  py::dict bars() const {
    std::vector<std::uint8_t> state;
    std::vector<double> damage, force, strain;
    sim().bar_snapshot(state, damage, force, &strain);
    py::dict d;
    d["state"] = py::array_t<std::uint8_t>(static_cast<py::ssize_t>(state.size()), state.data());
    d["damage"] = py::array_t<double>(static_cast<py::ssize_t>(damage.size()), damage.data());
    d["force"] = py::array_t<double>(static_cast<py::ssize_t>(force.size()), force.data());
    d["strain"] = py::array_t<double>(static_cast<py::ssize_t>(strain.size()), strain.data());
    py::array_t<bool> present(static_cast<py::ssize_t>(state.size()));
    bool* p = present.mutable_data();
    for (index_t b = 0; b < lattice().num_bars(); ++b)
      p[b] = lattice().bar_present(b);
    d["present"] = present;
    return d;
  }
  py::dict energies() const {
    const EnergyReport& r = body_->last_report();
    py::dict d;
    d["time"] = r.time;
    d["external_work"] = r.external_work;
    d["elastic"] = r.elastic;
    d["kinetic"] = r.kinetic;
    d["damage_dissipated"] = r.damage_dissipated;
    d["damping_dissipated"] = r.damping_dissipated;
    d["fatigue_dissipated"] = r.fatigue_dissipated;
    d["contact"] = r.contact;
    d["friction_dissipated"] = r.friction_dissipated;
    d["initial"] = r.initial;
    d["balance_error"] = r.balance_error;
    return d;
  }
  py::dict probes() const {
    py::dict d;
    const std::vector<double>& v = body_->last_probes();
    for (std::size_t i = 0; i < probe_names_.size() && i < v.size(); ++i)
      d[py::str(probe_names_[i])] = v[i];
    return d;
  }
  std::vector<std::string> velocity_sets() const {
    std::vector<std::string> s;
    for (const VelocitySpec& v : case_->spec.velocities)
      s.push_back(v.set);
    return s;
  }
  std::vector<std::string> load_sets() const {
    std::vector<std::string> s;
    for (const LoadSpec& l : case_->spec.loads)
      s.push_back(l.name);
    return s;
  }
  std::array<index_t, 3> modules() const {
    return {lattice().nx(), lattice().ny(), lattice().nz()};
  }
  double L() const { return lattice().L(); }
  std::uint64_t threads() const { return static_cast<std::uint64_t>(body_->threads()); }
  void set_threads_now(int n) { body_->set_threads(n > 0 ? n : g_default_threads); }

private:
  std::unique_ptr<BuiltCase> case_;
  std::unique_ptr<RunBody> body_;
  std::vector<std::string> probe_names_;
};

} // namespace
} // namespace ldem

PYBIND11_MODULE(_core, m) {
  using namespace ldem;
  m.doc() = "ldem's compiled core (use the package `ldem`)";
  g_default_threads = omp_get_max_threads();
  static py::exception<InputError> input_error(m, "InputError", PyExc_ValueError);
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p)
        std::rethrow_exception(p);
    } catch (const InputError& e) {
      input_error(e.what());
    }
  });
  m.def("check_case", &check_case, py::arg("name"), py::arg("text"));
  m.def("run", &run, py::arg("name"), py::arg("text"), py::arg("out"), py::arg("threads"),
        py::arg("plots"), py::arg("force"));
  m.def("resume", &resume, py::arg("out"), py::arg("threads"), py::arg("plots"), py::arg("end"));
  py::class_<PySimulation>(m, "Simulation")
      .def(py::init<const std::string&, const std::string&, int>(), py::arg("name"),
           py::arg("text"), py::arg("threads"))
      .def("step", &PySimulation::step, py::arg("n"))
      .def_property_readonly("time", &PySimulation::time)
      .def_property_readonly("step_count", &PySimulation::step_count)
      .def_property_readonly("dt", &PySimulation::dt)
      .def_property_readonly("modules", &PySimulation::modules)
      .def_property_readonly("L", &PySimulation::L)
      .def("displacement", [](const PySimulation& s) { return s.node_vectors(false); })
      .def("velocity", [](const PySimulation& s) { return s.node_vectors(true); })
      .def("reference_positions", &PySimulation::positions)
      .def("node_present", &PySimulation::node_present)
      .def("bar_nodes", &PySimulation::bar_nodes)
      .def("bars", &PySimulation::bars)
      .def("energies", &PySimulation::energies)
      .def("probes", &PySimulation::probes)
      .def("velocity_sets", &PySimulation::velocity_sets)
      .def("load_sets", &PySimulation::load_sets)
      .def("threads", &PySimulation::threads)
      .def("set_threads", &PySimulation::set_threads_now, py::arg("n"))
      .def("set_velocity_factor",
           [](PySimulation& s, std::size_t i, double f) { s.sim().set_velocity_factor(i, f); })
      .def("set_load_factor",
           [](PySimulation& s, std::size_t i, double f) { s.sim().set_load_factor(i, f); })
      .def("velocity_factor",
           [](const PySimulation& s, std::size_t i) { return s.sim().velocity_factor(i); })
      .def("load_factor",
           [](const PySimulation& s, std::size_t i) { return s.sim().load_factor(i); });
}
