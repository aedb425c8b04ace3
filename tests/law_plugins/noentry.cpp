// A shared library without the entry points.
extern "C" __attribute__((visibility("default"))) int not_a_law(void) { return 1; }
