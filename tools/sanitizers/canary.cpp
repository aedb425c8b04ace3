// sc-rt-sanitizer-canary: one deliberate bug per argument, built with the
// same flags as the rest of a sanitizer build (cmake/Sanitizers.cmake).
// tests/test_sanitizers.py runs it to prove that the build is instrumented
// and that the runtime options it uses turn a finding into a failed run:
//   heap-overflow    read past a heap array          (AddressSanitizer)
//   use-after-free   read a freed object             (AddressSanitizer)
//   leak             lose a heap block               (LeakSanitizer)
//   signed-overflow  INT_MAX + 1                     (UBSan)
//   float-cast       a huge double to int            (UBSan float-cast-overflow)
//   race             two threads write one int       (ThreadSanitizer)
//   ok               nothing: must exit 0
#include <climits>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <thread>

namespace {
// Opaque to the optimizer: the bugs must survive -O1.
volatile int g_sink;
int* volatile g_leak;
int g_shared;

int opaque(int x) {
  volatile int v = x;
  return v;
}
}  // namespace

int main(int argc, char** argv) {
  const char* what = argc > 1 ? argv[1] : "ok";
  if (!std::strcmp(what, "heap-overflow")) {
    int* p = new int[4]();
    g_sink = p[opaque(4)];
    delete[] p;
  } else if (!std::strcmp(what, "use-after-free")) {
    int* p = new int(1);
    delete p;
    g_sink = *p;
  } else if (!std::strcmp(what, "leak")) {
    g_leak = static_cast<int*>(std::malloc(64 * sizeof(int)));
    g_leak[0] = 1;
    g_leak = nullptr;
  } else if (!std::strcmp(what, "signed-overflow")) {
    g_sink = opaque(INT_MAX) + opaque(1);
  } else if (!std::strcmp(what, "float-cast")) {
    volatile double d = 1e300;
    g_sink = static_cast<int>(d);
  } else if (!std::strcmp(what, "race")) {
    std::thread a([] { for (int i = 0; i < 1000; ++i) g_shared = g_shared + 1; });
    std::thread b([] { for (int i = 0; i < 1000; ++i) g_shared = g_shared + 1; });
    a.join();
    b.join();
    g_sink = g_shared;
  } else if (std::strcmp(what, "ok")) {
    std::fprintf(stderr, "sc-rt-sanitizer-canary: unknown bug '%s'\n", what);
    return 2;
  }
  std::printf("sc-rt-sanitizer-canary: %s survived\n", what);
  return 0;
}
