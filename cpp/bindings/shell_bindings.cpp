// Bindings of the controller shell's policy classes (cpp/shell/input_gate.hpp,
// phase_lock.hpp, sensor_intake.hpp) into sc_rt._core, for unit tests of the gate and the
// scheduler without LCM or a clock. Times are monotonic ns (int).
#include <pybind11/eigen.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <limits>
#include <string>

#include "histogram.hpp"
#include "hmac.hpp"
#include "input_gate.hpp"
#include "phase_lock.hpp"
#include "sensor_bindings.hpp"
#include "sensor_intake.hpp"
#include "translate.hpp"

namespace py = pybind11;
using namespace sc_rt;
using py::arg;

void bind_shell(py::module_& m) {
  py::class_<LogHistogram>(m, "LogHistogram",
                           "Fixed-size log-linear histogram of durations [us] (cpp/shell/histogram.hpp): "
                           "the controller's whole-run statistics")
      .def(py::init<>())
      .def("add", &LogHistogram::add, py::arg("us"))
      .def(
          "add_many",
          [](LogHistogram& h, const std::vector<double>& v) {
            for (double x : v) h.add(x);
          },
          py::arg("values"))
      .def("quantile", &LogHistogram::quantile, py::arg("p"))
      .def_property_readonly("count", &LogHistogram::count)
      .def_property_readonly("max", &LogHistogram::max)
      .def_property_readonly("mean", &LogHistogram::mean)
      .def_property_readonly_static("BUCKETS", [](py::object) { return LogHistogram::kBuckets; });
  py::enum_<GateVerdict>(m, "GateVerdict", "What the controller shell does with one received state.")
      .value("Accept", GateVerdict::Accept)
      .value("Adopt", GateVerdict::Adopt)
      .value("Duplicate", GateVerdict::Duplicate)
      .value("OutOfOrder", GateVerdict::OutOfOrder)
      .value("SeqJump", GateVerdict::SeqJump)
      .value("ForeignSession", GateVerdict::ForeignSession)
      .value("InvalidCandidate", GateVerdict::InvalidCandidate)
      .value("Malformed", GateVerdict::Malformed)
      .value("TrailingBytes", GateVerdict::TrailingBytes);

  py::class_<GateCounts>(m, "GateCounts", "A snapshot of the input gate's counters.")
      .def_readonly("received", &GateCounts::received)
      .def_readonly("malformed", &GateCounts::malformed)
      .def_readonly("trailing_bytes", &GateCounts::trailing_bytes)
      .def_readonly("duplicate", &GateCounts::duplicate)
      .def_readonly("out_of_order", &GateCounts::out_of_order)
      .def_readonly("invalid_state", &GateCounts::invalid_state)
      .def_readonly("foreign_session", &GateCounts::foreign_session)
      .def_readonly("sessions_adopted", &GateCounts::sessions_adopted)
      .def_readonly("seq_jump", &GateCounts::seq_jump)
      .def_property_readonly("rejected", &GateCounts::rejected)
      .def("as_dict", [](const GateCounts& c) {
        py::dict d;
        d["received"] = c.received;
        d["malformed"] = c.malformed;
        d["trailing_bytes"] = c.trailing_bytes;
        d["duplicate"] = c.duplicate;
        d["out_of_order"] = c.out_of_order;
        d["invalid_state"] = c.invalid_state;
        d["foreign_session"] = c.foreign_session;
        d["sessions_adopted"] = c.sessions_adopted;
        d["seq_jump"] = c.seq_jump;
        return d;
      });

  // cpp/shell/hmac.hpp, for its test vectors (RFC 4231, FIPS 180-4) and the
  // Python side's agreement with the controller's tags
  auto bytes_of = [](const Sha256::Digest& d) {
    return py::bytes(reinterpret_cast<const char*>(d.data()), d.size());
  };
  m.def("sha256", [bytes_of](py::bytes data) {
        const std::string s = data;
        return bytes_of(Sha256::of(s.data(), s.size()));
      }, arg("data"), "SHA-256 of data (the controller's own, cpp/shell/hmac.hpp).");
  m.def("hmac_sha256", [bytes_of](py::bytes key, py::bytes data) {
        const std::string d = data;
        return bytes_of(HmacSha256(std::string(key)).mac(d.data(), d.size()));
      }, arg("key"), arg("data"), "HMAC-SHA256(key, data) (the controller's own, cpp/shell/hmac.hpp).");
  m.def("message_tag", [bytes_of](py::bytes key, const std::string& channel, py::bytes payload) {
        const std::string p = payload;
        return bytes_of(HmacSha256(std::string(key)).message_tag(channel, p.data(), p.size()));
      }, arg("key"), arg("channel"), arg("payload"),
      "The 32-byte trailer the controller appends: HMAC-SHA256(key, channel || 0x00 || payload).");

  py::class_<InputGate>(m, "InputGate",
                        "The controller's input gate: session adoption, duplicates, order, counters.")
      .def(py::init<int64_t>(), arg("session_timeout_ns"))
      .def_static("session_timeout_for", &InputGate::session_timeout_for, arg("stale_ns"),
                  "The controller's session timeout: max(stale_ns, 2 s) [ns].")
      .def("malformed", &InputGate::malformed, "A message that did not decode.")
      .def("trailing_bytes", &InputGate::trailing_bytes, "A message followed by extra bytes.")
      .def("offer", &InputGate::offer, arg("now_ns"), arg("session"), arg("seq"), arg("valid"),
           "A decoded state received at now_ns; valid: measurement_valid of its values.")
      .def_property_readonly("have_state", &InputGate::have_state)
      .def_property_readonly("session", &InputGate::session)
      .def_property_readonly("seq", &InputGate::seq)
      .def_property_readonly("last_rx_ns", &InputGate::last_rx_ns)
      .def_property_readonly("session_timeout_ns", &InputGate::session_timeout_ns)
      .def("counts", &InputGate::counts);

  py::class_<PhaseLock>(m, "PhaseLock",
                        "The real-time controller's deadlines, phase-locked to the state arrivals.")
      .def(py::init<int64_t, double, int64_t>(), arg("period_ns"), arg("phase_offset_us"),
           arg("start_ns"))
      .def("advance", &PhaseLock::advance, arg("used_fresh"), arg("rx_ns"), arg("now_ns"),
           "After the step woken at deadline: returns the next deadline (never before now_ns).")
      .def_property_readonly("deadline", &PhaseLock::deadline)
      .def_property_readonly("guard_ns", &PhaseLock::guard_ns)
      .def_property_readonly("period_ns", &PhaseLock::period_ns)
      .def_property_readonly("phase_offset_us", &PhaseLock::phase_offset_us)
      .def_property_readonly("locked", &PhaseLock::locked);

  py::class_<SensorCounts>(m, "SensorCounts", "The sensor intake's counters (sensor_intake.hpp).")
      .def_property_readonly("used", [](const SensorCounts& c) {
        return py::make_tuple(c.used[0], c.used[1], c.used[2]);
      }, "(gyro, star tracker, tachometer) samples applied")
      .def_property_readonly("mag_used", [](const SensorCounts& c) { return c.used[3]; },
                             "magnetometer samples applied")
      .def_readonly("malformed", &SensorCounts::malformed)
      .def_readonly("invalid", &SensorCounts::invalid)
      .def_readonly("out_of_order", &SensorCounts::out_of_order)
      .def_readonly("too_old", &SensorCounts::too_old)
      .def_readonly("foreign", &SensorCounts::foreign)
      .def_readonly("before_fix", &SensorCounts::before_fix)
      .def_property_readonly("rejected", &SensorCounts::rejected);
  py::class_<SensorIntake>(m, "SensorIntake",
                           "The controller's sensor intake: sessions, order, checks, into the Estimator.")
      .def(py::init<const MekfParams&, bool, const Vec3&, std::size_t>(), arg("p"), arg("use_estimate"),
           arg("sigma0"), arg("queue") = 4096)
      .def("offer_gyro", [](SensorIntake& s, int64_t session, int64_t seq, double t, const Vec3& w, int output) {
             s.offer_gyro(session, seq, GyroSample{t, w, output});
           }, arg("session"), arg("seq"), arg("t"), arg("omega"), arg("output") = 0)
      .def("offer_star", [](SensorIntake& s, int64_t session, int64_t seq, double te, double td,
                            const Vec3& sigma) { s.offer_star(session, seq, StarSample{te, td, sigma}); },
           arg("session"), arg("seq"), arg("t_exposure"), arg("t_delivery"), arg("sigma_BN"))
      .def("offer_tach", [](SensorIntake& s, int64_t session, int64_t seq, double t, const Vec4& w) {
             s.offer_tach(session, seq, TachSample{t, w});
           }, arg("session"), arg("seq"), arg("t"), arg("wheel_speed"))
      .def("offer_mag", [](SensorIntake& s, int64_t session, int64_t seq, double t, const Vec3& B_S) {
             s.offer_mag(session, seq, MagSample{t, B_S});
           }, arg("session"), arg("seq"), arg("t"), arg("B_S"), "A magnetometer's sample B_S [T] (sensor frame).")
      .def("mount_magnetometer", &SensorIntake::mount_magnetometer, arg("R_SB"),
           "The magnetometer's known mounting R_SB [-] (body to sensor): its samples are used from now on.")
      .def_property_readonly("magnetometer_mounted", &SensorIntake::magnetometer_mounted)
      .def_property_readonly("field_B", &SensorIntake::field_B,
                             "[T] the latest magnetometer sample rotated to B (NaN: none yet)")
      .def("malformed", &SensorIntake::malformed)
      .def("use", &SensorIntake::use, arg("session"), arg("t"))
      .def_property_readonly("ready", &SensorIntake::ready)
      .def_property_readonly("use_estimate", &SensorIntake::use_estimate)
      .def_property_readonly("session", &SensorIntake::session)
      .def_property_readonly("queued", &SensorIntake::queued)
      .def("measure", [](SensorIntake& s, const Measurement& truth) {
             NavTelemetry tel;
             tel.bias_true.setConstant(std::numeric_limits<double>::quiet_NaN());
             tel.att_error.setConstant(std::numeric_limits<double>::quiet_NaN());
             const Measurement m = s.measure(truth, &tel);
             return py::make_tuple(m, sc_rt_bind::pack(tel));
           }, arg("truth"), "(Measurement, telemetry (NAV_SIZE,)) as the controller uses them.")
      .def("counts", &SensorIntake::counts)
      .def_property_readonly("estimator", &SensorIntake::estimator, py::return_value_policy::reference_internal);
  m.def("nav_from_config_bytes", [](py::bytes data) {
        const std::string b = data;
        const NavSetup n = nav_from_bytes(b.data(), int(b.size()));
        return py::make_tuple(n.enabled, n.use_estimate, n.mekf, n.sigma0,
                              n.mag_enabled ? py::object(py::cast(n.mag_R_SB)) : py::object(py::none()));
      }, arg("data"),
      "(enabled, use_estimate, MekfParams, sigma0, mag_R_SB) of an encoded controller_config_t, as the controller "
      "reads it (mag_R_SB: the magnetometer's mounting [-], None: no magnetometer samples).");
}
