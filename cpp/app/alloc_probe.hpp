// The allocation probe (issue #31, "no heap allocation on the step path").
//
// sc-rt-controller-alloc is sc-rt-controller linked with alloc_counter.cpp,
// which defines these two functions and replaces the process's malloc
// family (so also operator new, LCM's C library, GLib and a law plugin) by
// counting wrappers around glibc's allocator. In sc-rt-controller they are
// not defined: the weak references are null and the shell skips the probe.
// The shell arms the counter after a warm-up of kAllocWarmupSteps steps and
// reads it at the end of every later step, so the count covers receive,
// decode, gate, sensor intake, law, encode, HMAC and publish of every step
// after the warm-up, and nothing of the shutdown (tests/test_no_alloc.py).
#pragma once
#include <cstdint>

extern "C" {
void sc_rt_alloc_arm() __attribute__((weak));
long long sc_rt_alloc_count() __attribute__((weak));
}

namespace sc_rt_controller {
// first-use allocations (LCM's channel caches, the first session) happen here
constexpr int64_t kAllocWarmupSteps = 100;
inline bool alloc_probe_linked() { return sc_rt_alloc_count != nullptr; }
}  // namespace sc_rt_controller
