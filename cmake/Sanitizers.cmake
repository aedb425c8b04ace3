# SC_RT_SANITIZE: build everything (core, shell, controller, bindings) under
# GCC/Clang sanitizers. Empty (the default): no change to the build.
#   -DSC_RT_SANITIZE=address,undefined   AddressSanitizer + UBSan (+ float-cast-overflow)
#   -DSC_RT_SANITIZE=thread              ThreadSanitizer
# Every UBSan finding aborts (-fno-sanitize-recover): a run is clean or fails.
# tests/test_sanitizers.py (`make check-sanitizers`, and `make test`) builds
# build/asan and build/tsan this way and runs them. The prebuilt liblcm.a of
# the lcm wheel and the system's GLib are not instrumented: ASan still sees
# their heap through its malloc interceptor; TSan sees their pthread and
# file-descriptor calls only (tools/sanitizers/tsan.supp).
set(SC_RT_SANITIZE "" CACHE STRING
    "Sanitizers for every target: empty (default), 'address,undefined' or 'thread'")
if(SC_RT_SANITIZE)
  string(REPLACE "," ";" _scrt_san "${SC_RT_SANITIZE}")
  foreach(_s IN LISTS _scrt_san)
    if(NOT _s MATCHES "^(address|undefined|thread|leak)$")
      message(FATAL_ERROR "SC_RT_SANITIZE: unknown sanitizer '${_s}' (address, undefined, thread)")
    endif()
  endforeach()
  if("thread" IN_LIST _scrt_san AND ("address" IN_LIST _scrt_san OR "leak" IN_LIST _scrt_san))
    message(FATAL_ERROR "SC_RT_SANITIZE: thread cannot be combined with address/leak")
  endif()
  set(_scrt_flags "-fsanitize=${SC_RT_SANITIZE}" -fno-omit-frame-pointer)
  if("undefined" IN_LIST _scrt_san)
    # float-cast-overflow is not part of -fsanitize=undefined: a NaN or huge
    # double converted to an integer (the shell converts times and rates).
    list(APPEND _scrt_flags -fsanitize=float-cast-overflow -fno-sanitize-recover=all)
  endif()
  add_compile_options(${_scrt_flags})
  add_link_options(${_scrt_flags})
  message(STATUS "sc-rt: sanitizers ${SC_RT_SANITIZE} (${_scrt_flags})")
  # One deliberate bug per argument: proves the instrumentation and the
  # runtime options catch what they should (tests/test_sanitizers.py).
  find_package(Threads REQUIRED)
  add_executable(sc-rt-sanitizer-canary "${PROJECT_SOURCE_DIR}/tools/sanitizers/canary.cpp")
  target_link_libraries(sc-rt-sanitizer-canary PRIVATE Threads::Threads)
endif()

# GCC 12's -fsanitize=vptr (part of undefined) miscompiles a call through a
# pointer to member function reached through a polymorphic object: the check
# loads a vptr from address 0 (SEGV, or "member access within null pointer").
# LCM's typed member-handler subscription, lcm::LCMMHSubscription::cb_func
# (lcm-cpp-impl.hpp: (subs->handler->*subs->handlerMethod)(...)), is such a
# call, and sc-rt-lcm-pingpong is its only user (the controller subscribes
# plain functions). A well-defined 20-line program reproduces it (GCC only;
# also reported in dotnet/runtime#73927). So: no vptr check in that one tool.
if(SC_RT_SANITIZE MATCHES "undefined" AND CMAKE_CXX_COMPILER_ID STREQUAL "GNU")
  cmake_language(DEFER CALL set_property TARGET sc-rt-lcm-pingpong APPEND PROPERTY
                 COMPILE_OPTIONS -fno-sanitize=vptr)
endif()
