// sc-rt-logger: every message on an LCM bus into an lcm-logger-format log,
// without losing one at the bench's rates. lcm-logger subscribes with LCM's
// default 30-message queue: a burst of ~14,000 messages/s in lockstep lost up
// to 162 of 601 states (RcvbufErrors 0). This logger is the same file format
// (lcm's own eventlog writer) behind a deep subscription queue, writing from
// its own thread and flushing every --flush-interval ms; SIGINT/SIGTERM
// drain what is queued, then close. Its exit summary (stderr, JSON) says how
// many events it wrote and the deepest its queue got. With --ack-channel it
// says how far it has written: a log_ack_t (the messages of --count-channel
// written so far) after every 8 of them, which a lockstep bench waits for so
// that it never outruns its logger.
//   sc-rt-logger --lcm-url URL [--flush-interval MS] [--queue N]
//                [--ack-channel CH --count-channel CH] FILE
#include <lcm/eventlog.h>
#include <lcm/lcm.h>
#include <sc_rt_lcm/log_ack_t.hpp>
#include <signal.h>
#include <time.h>

#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

namespace {
std::atomic<bool> g_stop{false};
void on_signal(int) { g_stop = true; }

int64_t mono_ms() {
  timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return int64_t(ts.tv_sec) * 1000 + ts.tv_nsec / 1000000;
}

struct Ctx {
  lcm_eventlog_t* log = nullptr;
  lcm_subscription_t* sub = nullptr;
  int64_t events = 0;
  int64_t write_errors = 0;
  int deepest = 0;
  std::string ack_channel, count_channel;  // empty: no acknowledgements
  int64_t counted = 0;  // messages on count_channel written
};

// A log_ack_t on the ack channel: how far the log is written.
void publish_ack(lcm_t* lcm, const Ctx& c) {
  sc_rt_lcm::log_ack_t m;
  timespec ts;
  clock_gettime(CLOCK_REALTIME, &ts);
  m.utime = int64_t(ts.tv_sec) * 1000000 + ts.tv_nsec / 1000;
  m.counted = c.counted;
  m.events = c.events;
  std::vector<uint8_t> buf(size_t(m.getEncodedSize()));
  m.encode(buf.data(), 0, int(buf.size()));
  lcm_publish(lcm, c.ack_channel.c_str(), buf.data(), static_cast<unsigned int>(buf.size()));
}

// A write or flush of the log failed (a full disk, a file gone): the log can
// no longer be the run's evidence. Said once, and the logger stops, so that
// the bench (which watches this process) stops the run within its poll.
void write_failed(Ctx& c) {
  if (c.write_errors++ == 0) {
    std::fprintf(stderr, "sc-rt-logger: cannot write the log (%s): stopping\n", std::strerror(errno));
  }
  g_stop = true;
}

void on_message(const lcm_recv_buf_t* rbuf, const char* channel, void* user) {
  auto* c = static_cast<Ctx*>(user);
  if (!c->ack_channel.empty() && c->ack_channel == channel) return;  // its own acknowledgements
  lcm_eventlog_event_t ev{};
  ev.eventnum = c->events;
  ev.timestamp = rbuf->recv_utime;
  ev.channellen = static_cast<int32_t>(std::strlen(channel));
  ev.datalen = static_cast<int32_t>(rbuf->data_size);
  ev.channel = const_cast<char*>(channel);
  ev.data = rbuf->data;
  if (lcm_eventlog_write_event(c->log, &ev) != 0) {
    write_failed(*c);
  }
  ++c->events;
  if (!c->count_channel.empty() && c->count_channel == channel) ++c->counted;
  const int q = lcm_subscription_get_queue_size(c->sub);
  if (q > c->deepest) c->deepest = q;
}

const char kUsage[] =
    "usage: sc-rt-logger --lcm-url URL [--flush-interval MS] [--queue N]\n"
    "                    [--ack-channel CH --count-channel CH] FILE\n"
    "Every message on the bus into FILE (lcm-logger's format), with a deep queue;\n"
    "with --ack-channel, a log_ack_t there saying how many messages of\n"
    "--count-channel are written (after every 8).\n";
}  // namespace

int main(int argc, char** argv) {
  std::string url, path, ack_channel, count_channel;
  long flush_ms = 20, queue = 1000000;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&](const std::string& name) -> std::string {
      if (a.rfind(name + "=", 0) == 0) return a.substr(name.size() + 1);
      if (i + 1 >= argc) {
        std::fprintf(stderr, "sc-rt-logger: %s needs a value\n", name.c_str());
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--help" || a == "-h") {
      std::fputs(kUsage, stdout);
      return 0;
    } else if (a == "--lcm-url" || a.rfind("--lcm-url=", 0) == 0) {
      url = value("--lcm-url");
    } else if (a == "--flush-interval" || a.rfind("--flush-interval=", 0) == 0) {
      flush_ms = std::atol(value("--flush-interval").c_str());
    } else if (a == "--queue" || a.rfind("--queue=", 0) == 0) {
      queue = std::atol(value("--queue").c_str());
    } else if (a == "--ack-channel" || a.rfind("--ack-channel=", 0) == 0) {
      ack_channel = value("--ack-channel");
    } else if (a == "--count-channel" || a.rfind("--count-channel=", 0) == 0) {
      count_channel = value("--count-channel");
    } else if (!a.empty() && a[0] != '-' && path.empty()) {
      path = a;
    } else {
      std::fprintf(stderr, "sc-rt-logger: unknown argument '%s'\n%s", a.c_str(), kUsage);
      return 2;
    }
  }
  if (path.empty() || flush_ms <= 0 || queue <= 0 || ack_channel.empty() != count_channel.empty()) {
    std::fputs(kUsage, stderr);
    return 2;
  }
  lcm_t* lcm = lcm_create(url.empty() ? nullptr : url.c_str());
  if (lcm == nullptr) {
    std::fprintf(stderr, "sc-rt-logger: cannot start LCM on %s\n", url.c_str());
    return 3;
  }
  Ctx c;
  c.ack_channel = ack_channel;
  c.count_channel = count_channel;
  c.log = lcm_eventlog_create(path.c_str(), "w");
  if (c.log == nullptr) {
    std::fprintf(stderr, "sc-rt-logger: cannot write %s\n", path.c_str());
    return 2;
  }
  struct sigaction sa{};
  sa.sa_handler = on_signal;
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
  c.sub = lcm_subscribe(lcm, ".*", on_message, &c);
  lcm_subscription_set_queue_capacity(c.sub, static_cast<int>(queue));
  int64_t next_flush = mono_ms() + flush_ms;
  int64_t acked = 0;
  constexpr int64_t kAckEvery = 8;
  while (!g_stop) {
    lcm_handle_timeout(lcm, static_cast<int>(flush_ms));
    if (!c.ack_channel.empty() && c.counted - acked >= kAckEvery) {
      publish_ack(lcm, c);  // written to the log's stream: a crash of the bench loses none of it
      acked = c.counted;
    }
    if (mono_ms() >= next_flush) {
      if (std::fflush(c.log->f) != 0) {  // a full disk shows here first: as a failed write
        write_failed(c);
        break;
      }
      next_flush = mono_ms() + flush_ms;
    }
  }
  while (lcm_handle_timeout(lcm, 0) > 0) {  // what is queued already: into the log too
  }
  std::fflush(c.log->f);
  lcm_eventlog_destroy(c.log);
  lcm_unsubscribe(lcm, c.sub);
  lcm_destroy(lcm);
  std::fprintf(stderr, "{\"events\": %lld, \"write_errors\": %lld, \"deepest_queue\": %d, \"queue\": %ld}\n",
               static_cast<long long>(c.events), static_cast<long long>(c.write_errors), c.deepest, queue);
  return c.write_errors ? 1 : 0;
}
