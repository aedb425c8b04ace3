// Claims interface version 99: refused before any C++ type is touched.
extern "C" __attribute__((visibility("default"))) int sc_rt_law_api_version(void) { return 99; }
