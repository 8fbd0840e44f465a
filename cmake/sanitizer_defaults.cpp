// Linked into every executable of an ASan build (STROMA_ASAN): defaults the sanitizer runtimes
// read at start-up, so a plain run of any binary (tests, `stroma`, fuzz targets, gtest's test
// discovery at build time) needs no environment variables.

extern "C" {

// LeakSanitizer: OpenBLAS (through CHOLMOD) loads libgfortran, whose start-up strdup()s two
// strings it never frees — 14 bytes, once per process, not ours. Everything else is reported.
const char* __lsan_default_suppressions() { return "leak:libgfortran.so\n"; }

}
