# SPDX-License-Identifier: MIT
# lodkit front door. `make demo` and `make test` work on a fresh Debian 12
# machine: they install the packages they need and fetch the sample models.
MAKEFLAGS += --no-print-directory
JOBS ?= $(shell nproc 2>/dev/null || echo 2)
BUILD ?= build
ASAN_BUILD ?= build-asan
FUZZ_BUILD ?= build-fuzz
TSAN_BUILD ?= build-tsan
CORE_BUILD ?= build-core
# WERROR=ON turns compiler warnings into errors (.ci/run sets it).
WERROR ?= OFF
FUZZ_SECONDS ?= 300

.PHONY: all deps samples build asan fuzz-build tsan demo test test-release test-asan test-tsan test-core bench fuzz install clean

all: build

deps:
	bash scripts/install-deps.sh

samples:
	bash scripts/fetch-samples.sh

build:
	cmake -S . -B $(BUILD) -DCMAKE_BUILD_TYPE=Release -DLODKIT_WERROR=$(WERROR) >/dev/null
	cmake --build $(BUILD) -j $(JOBS)

# Sanitizer build with clang: ASan + UBSan, for the test suite.
asan:
	cmake -S . -B $(ASAN_BUILD) -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_C_FLAGS_RELWITHDEBINFO="-O1 -g" -DCMAKE_C_COMPILER=clang \
	  -DLODKIT_SANITIZE=ON -DLODKIT_FUZZ=OFF -DLODKIT_BENCHES=OFF -DLODKIT_WERROR=$(WERROR) >/dev/null
	cmake --build $(ASAN_BUILD) -j $(JOBS)

# The libFuzzer targets (ASan + UBSan too), in a build of their own: their
# coverage instrumentation (-fsanitize=fuzzer-no-link on the whole library)
# more than doubles the CPU time of everything linked with it, which the
# test suite does not need. Only the fuzz targets are built; their short
# smoke runs (fuzz/CMakeLists.txt) are part of `make test-asan`.
fuzz-build:
	cmake -S . -B $(FUZZ_BUILD) -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_C_FLAGS_RELWITHDEBINFO="-O1 -g" -DCMAKE_C_COMPILER=clang \
	  -DLODKIT_SANITIZE=ON -DLODKIT_FUZZ=ON -DLODKIT_TESTS=OFF -DLODKIT_BENCHES=OFF -DLODKIT_WERROR=$(WERROR) >/dev/null
	cmake --build $(FUZZ_BUILD) -j $(JOBS) --target fuzz_targets

# ThreadSanitizer build with clang: only what the tests labelled `threads`
# need (the target threads_tests, see tests/CMakeLists.txt).
tsan:
	cmake -S . -B $(TSAN_BUILD) -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_C_FLAGS_RELWITHDEBINFO="-O1 -g" -DCMAKE_C_COMPILER=clang \
	  -DLODKIT_TSAN=ON -DLODKIT_WERROR=$(WERROR) >/dev/null
	cmake --build $(TSAN_BUILD) -j $(JOBS) --target threads_tests

demo: deps samples build
	bash scripts/demo.sh $(BUILD)/lodkit

test-release: build
	cd $(BUILD) && ctest --output-on-failure -j $(JOBS)

# intercept_tls_get_addr=0: LeakSanitizer misreads the range of some
# dlopen'd libraries' dynamic TLS blocks (Mesa's, here) as glibc 2.19's and
# its tracer crashes scanning it (google/sanitizers#1322: "Tracer caught
# signal 11", DTLS at 0xb66); which block gets misread moves with the
# address layout (`lodkit splat --passes=2` on tests/data/hostile/num/
# fltmax.obj after the splat shaders grew a varying). Leaks are still
# detected: static TLS, stacks and globals are scanned as before.
test-asan: asan fuzz-build
	cd $(ASAN_BUILD) && ASAN_OPTIONS=detect_leaks=1:abort_on_error=1:intercept_tls_get_addr=0 \
	  UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 ctest --output-on-failure -j $(JOBS)
	cd $(FUZZ_BUILD) && ASAN_OPTIONS=detect_leaks=1:abort_on_error=1:intercept_tls_get_addr=0 \
	  UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 ctest --output-on-failure -j $(JOBS)

# The core library alone (every component off), on a machine with only the
# core's packages (scripts/install-deps.sh --core): the core tests on
# procedural shapes and the layout check.
test-core:
	bash scripts/install-deps.sh --core
	cmake -S . -B $(CORE_BUILD) -DCMAKE_BUILD_TYPE=Release -DLODKIT_WERROR=$(WERROR) \
	  -DLODKIT_GL=OFF -DLODKIT_DEM=OFF -DLODKIT_SERVE=OFF >/dev/null
	cmake --build $(CORE_BUILD) -j $(JOBS)
	cd $(CORE_BUILD) && ctest --output-on-failure -j $(JOBS)

# The concurrency tests under ThreadSanitizer. Reports go to files, so that
# one from a `lodkit` a test script runs is seen even if the script ignores
# its exit status; any report fails the suite. tests/tsan.supp names what
# may be ignored inside uninstrumented libraries, never lodkit code.
# Suppressions match function names, so reports must be symbolized: without
# llvm-symbolizer every frame is <null> and nothing matches.
test-tsan: tsan
	@command -v llvm-symbolizer >/dev/null || { echo "test-tsan: needs llvm-symbolizer (Debian package: llvm); run scripts/install-deps.sh" >&2; exit 1; }
	rm -rf $(TSAN_BUILD)/tsan-reports && mkdir -p $(TSAN_BUILD)/tsan-reports
	cd $(TSAN_BUILD) && TSAN_OPTIONS="halt_on_error=1 second_deadlock_stack=1 suppressions=$(CURDIR)/tests/tsan.supp external_symbolizer_path=$$(command -v llvm-symbolizer) log_path=$$PWD/tsan-reports/report" \
	  ctest --output-on-failure -j $(JOBS) -L threads; status=$$?; \
	  if ls tsan-reports | grep -q .; then cat tsan-reports/*; echo "ThreadSanitizer: reports above" >&2; exit 1; fi; \
	  exit $$status

# The whole suite: optimised build, then under ASan + UBSan (+ fuzz smoke);
# the concurrency tests again under ThreadSanitizer; the core library alone.
test: deps samples
	$(MAKE) --no-print-directory test-release
	$(MAKE) --no-print-directory test-asan
	$(MAKE) --no-print-directory test-tsan
	$(MAKE) --no-print-directory test-core

bench: samples
	bash scripts/install-deps.sh --bench
	bash scripts/fetch-samples.sh --bench
	$(MAKE) --no-print-directory build
	bash bench/run.sh $(BUILD)

# FUZZ_SECONDS per target, or FUZZ_RUNS executions per target (a campaign:
# make fuzz FUZZ_RUNS=10000000); then `bash fuzz/run.sh --merge build-fuzz`.
fuzz: deps samples fuzz-build
	FUZZ_SECONDS=$(FUZZ_SECONDS) FUZZ_RUNS=$(FUZZ_RUNS) bash fuzz/run.sh $(FUZZ_BUILD)

install: build
	cmake --install $(BUILD)

clean:
	rm -rf $(BUILD) $(ASAN_BUILD) $(FUZZ_BUILD) $(TSAN_BUILD) $(CORE_BUILD)
