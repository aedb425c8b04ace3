// Counting heap allocator for sc-rt-controller-alloc (alloc_probe.hpp).
//
// Defining the malloc family in the executable interposes it for the whole
// process (ELF symbol lookup finds the executable first): libstdc++'s
// operator new, the statically linked LCM, GLib and a dlopen'ed law plugin
// all come here. Each wrapper forwards to glibc's own entry point
// (__libc_malloc etc.) and, once armed, counts one allocation. free is
// forwarded without counting. Linux/glibc only, and never combined with a
// sanitizer (which replaces malloc itself).
#include <atomic>
#include <cerrno>
#include <cstddef>

#include "alloc_probe.hpp"

extern "C" {
void* __libc_malloc(std::size_t);
void* __libc_calloc(std::size_t, std::size_t);
void* __libc_realloc(void*, std::size_t);
void* __libc_memalign(std::size_t, std::size_t);
void* __libc_valloc(std::size_t);
void* __libc_pvalloc(std::size_t);
void __libc_free(void*);
}

namespace {
std::atomic<bool> g_armed{false};
std::atomic<long long> g_count{0};
inline void tick() {
  if (g_armed.load(std::memory_order_relaxed)) g_count.fetch_add(1, std::memory_order_relaxed);
}
}  // namespace

extern "C" {
void* malloc(std::size_t n) {
  tick();
  return __libc_malloc(n);
}
void* calloc(std::size_t k, std::size_t n) {
  tick();
  return __libc_calloc(k, n);
}
void* realloc(void* p, std::size_t n) {
  tick();
  return __libc_realloc(p, n);
}
void free(void* p) { __libc_free(p); }
void* memalign(std::size_t a, std::size_t n) {
  tick();
  return __libc_memalign(a, n);
}
void* aligned_alloc(std::size_t a, std::size_t n) {
  tick();
  return __libc_memalign(a, n);
}
int posix_memalign(void** out, std::size_t a, std::size_t n) {
  tick();
  void* p = __libc_memalign(a, n);
  if (p == nullptr) return ENOMEM;
  *out = p;
  return 0;
}
void* valloc(std::size_t n) {
  tick();
  return __libc_valloc(n);
}
void* pvalloc(std::size_t n) {
  tick();
  return __libc_pvalloc(n);
}

void sc_rt_alloc_arm() { g_armed.store(true); }
long long sc_rt_alloc_count() { return g_count.load(); }
}
