// sc-rt-lcm-pingpong: the LCM round-trip floor on this machine, with the
// message sizes of the lockstep loop (plant_state_t out, wheel_cmd_t back).
//   sc-rt-lcm-pingpong --role pong --lcm-url URL            (echoes until SIGTERM)
//   sc-rt-lcm-pingpong --role ping --lcm-url URL --count N  (prints JSON percentiles)
#include <signal.h>
#include <time.h>

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <lcm/lcm-cpp.hpp>
#include <sc_rt_lcm/plant_state_t.hpp>
#include <sc_rt_lcm/wheel_cmd_t.hpp>
#include <string>

#include "defaults.hpp"
#include <vector>

namespace {
std::atomic<bool> g_stop{false};
void on_signal(int) { g_stop = true; }
int64_t mono_ns() {
  timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return int64_t(ts.tv_sec) * 1000000000LL + ts.tv_nsec;
}
struct Pong {
  lcm::LCM* lc;
  void on(const lcm::ReceiveBuffer*, const std::string&, const sc_rt_lcm::plant_state_t* s) {
    sc_rt_lcm::wheel_cmd_t c{};
    c.seq = s->seq;
    c.state_seq = s->seq;
    lc->publish("PONG", &c);
  }
};
struct Ping {
  int64_t got = -1;
  void on(const lcm::ReceiveBuffer*, const std::string&, const sc_rt_lcm::wheel_cmd_t* c) { got = c->state_seq; }
};
}  // namespace

int main(int argc, char** argv) {
  std::string role, url = SCRT_DEFAULT_LCM_URL;
  long count = 20000;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string a = argv[i];
    if (a == "--role") role = argv[i + 1];
    else if (a == "--lcm-url") url = argv[i + 1];
    else if (a == "--count") count = std::atol(argv[i + 1]);
  }
  if (role != "ping" && role != "pong") {
    std::fprintf(stderr, "usage: sc-rt-lcm-pingpong --role ping|pong [--lcm-url URL] [--count N]\n");
    return 2;
  }
  lcm::LCM lc(url);
  if (!lc.good()) {
    std::fprintf(stderr, "sc-rt-lcm-pingpong: cannot start LCM on %s\n", url.c_str());
    return 3;
  }
  signal(SIGTERM, on_signal);
  signal(SIGINT, on_signal);
  if (role == "pong") {
    Pong p{&lc};
    lc.subscribe("PING", &Pong::on, &p);
    std::fprintf(stderr, "pong ready\n");
    while (!g_stop) lc.handleTimeout(100);
    return 0;
  }
  Ping p;
  lc.subscribe("PONG", &Ping::on, &p);
  std::vector<double> rtt;
  rtt.reserve(size_t(count));
  sc_rt_lcm::plant_state_t s{};
  long lost = 0;
  for (long k = -200; k < count && !g_stop; ++k) {  // 200 warm-up round trips
    s.seq = k + 200;
    const int64_t t0 = mono_ns();
    lc.publish("PING", &s);
    while (p.got != s.seq && mono_ns() - t0 < 200000000LL) lc.handleTimeout(200);
    const int64_t t1 = mono_ns();
    if (p.got != s.seq) ++lost;
    else if (k >= 0) rtt.push_back(double(t1 - t0) / 1e3);
  }
  std::sort(rtt.begin(), rtt.end());
  auto q = [&](double f) { return rtt.empty() ? 0.0 : rtt[std::min(rtt.size() - 1, size_t(f * (rtt.size() - 1)))]; };
  std::printf("{\"n\": %zu, \"lost\": %ld, \"rtt_us\": {\"p50\": %.3f, \"p99\": %.3f, \"max\": %.3f, \"min\": %.3f}}\n",
              rtt.size(), lost, q(0.5), q(0.99), rtt.empty() ? 0.0 : rtt.back(), rtt.empty() ? 0.0 : rtt.front());
  return 0;
}
