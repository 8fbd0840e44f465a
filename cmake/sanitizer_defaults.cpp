// Linked into every executable of an ASan build (STROMA_ASAN): defaults the sanitizer runtimes
// read at start-up, so a plain run of any binary (tests, `stroma`, fuzz targets, gtest's test
// discovery at build time) needs no environment variables.

extern "C" {

// LeakSanitizer: OpenBLAS (through CHOLMOD) loads libgfortran, whose start-up strdup()s two
// strings it never frees — 14 bytes, once per process; Mesa's OSMesa keeps 480 bytes of its
// make-current bookkeeping after OSMesaDestroyContext (once per renderer process, measured in a
// soak: bench/soak.sh with LSAN=1). Neither is ours; everything else is reported.
const char* __lsan_default_suppressions() { return "leak:libgfortran.so\nleak:libOSMesa.so\n"; }

}
