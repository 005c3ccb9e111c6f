# The two commands of the README: `make demo` and `make test`.
BUILD_DIR ?= build
ASAN_DIR  ?= build-asan
FUZZ_DIR  ?= build-fuzz
TSAN_DIR  ?= build-tsan
FUZZ_SECONDS ?= 20
JOBS      ?= $(shell nproc)
CMAKE_FLAGS ?=

.PHONY: all deps build test demo sanitize tsan fuzz bench image clean

all: build

deps:
	bash scripts/install-deps.sh

# scripts/build.sh is the build that CI and the container image (deploy/Dockerfile) share.
build: deps
	JOBS=$(JOBS) bash scripts/build.sh $(BUILD_DIR) $(CMAKE_FLAGS)

test: build
	cd $(BUILD_DIR) && { ctest --output-on-failure -O ctest-output.log -j $(JOBS) || { bash $(CURDIR)/scripts/ctest-failures.sh .; exit 1; }; }

demo: build
	bash scripts/demo.sh $(BUILD_DIR)

# Every test again under AddressSanitizer and UndefinedBehaviorSanitizer, built by clang at
# -O2 (CMakeLists.txt). Not with the fuzz targets: their coverage instrumentation on every
# library made the tests 2.8x slower (the PA-10's time-optimal path C: 13.4 s against 4.8 s);
# `make fuzz` builds its own tree, from the compiler cache after a first build. Left
# out (cmake/slow_tests.cmake): tests labelled slow (a minute or more even in Release) or
# heavy (numerical property tests of 20 s or more under the sanitizers), and the tests of
# what is not C++ (interop: the Python and Node clients; deploy; web: the browser), whose
# server runs under the sanitizers in the server's own tests.
# -g1: line tables for the sanitizers' stack traces, without the full debug information
# whose generation and linking are a large part of this build's time.
SANITIZE_CONFIG = -DCMAKE_BUILD_TYPE=Debug -DCMAKE_CXX_FLAGS_DEBUG=-g1 -DCMAKE_CXX_COMPILER=clang++ \
  -DGEOTRAJ_SANITIZE=ON -DGEOTRAJ_BUILD_BENCH=OFF -DGEOTRAJ_NPM_TESTS=OFF
sanitize: deps
	cmake -S . -B $(ASAN_DIR) $(SANITIZE_CONFIG) $(CMAKE_FLAGS)
	cmake --build $(ASAN_DIR) -j $(JOBS)
	cd $(ASAN_DIR) && export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 && \
	  { ctest --output-on-failure -O ctest-output.log -j $(JOBS) -LE '^(slow|heavy|interop|deploy|web)$$' || { bash $(CURDIR)/scripts/ctest-failures.sh .; exit 1; }; }

# The server's concurrency tests under ThreadSanitizer: every RPC at once, cancelled midway,
# the worker pool, health watches, the acceptor, streams (docs/reliability.md). gRPC and
# protobuf come from Debian uninstrumented; tests/tsan.supp names what is theirs.
TSAN_TARGETS = server_concurrency_test server_hostile_test server_acceptor_test server_stream_test server_live_test server_web_test geotrajd
TSAN_TESTS = ^server\.(Concurrency|Workers|HealthWatch|AcceptorTest|HealthState|Cancel|Connections|Deadlines|StreamTest|Live|LiveDrain|LiveTokens|LiveAdmission|LiveWriteDeadline|Web)\.
tsan: deps
	cmake -S . -B $(TSAN_DIR) -DCMAKE_BUILD_TYPE=Debug -DCMAKE_CXX_FLAGS_DEBUG=-g1 -DGEOTRAJ_TSAN=ON -DGEOTRAJ_BUILD_BENCH=OFF -DGEOTRAJ_NPM_TESTS=OFF $(CMAKE_FLAGS)
	cmake --build $(TSAN_DIR) -j $(JOBS) --target $(TSAN_TARGETS)
	cd $(TSAN_DIR) && export TSAN_OPTIONS="halt_on_error=1 second_deadlock_stack=1 ignore_noninstrumented_modules=1 suppressions=$(CURDIR)/tests/tsan.supp" && \
	  { ctest --output-on-failure -O ctest-output.log -j $(JOBS) -R '$(TSAN_TESTS)' || { bash $(CURDIR)/scripts/ctest-failures.sh .; exit 1; }; }

# libFuzzer targets (clang, ASan+UBSan, coverage) on the service's request parsing, validation
# and planning: the regression inputs, then FUZZ_SECONDS per target, as many targets at once
# as there are cores (docs/reliability.md).
fuzz: deps
	bash scripts/fuzz.sh $(FUZZ_DIR) $(FUZZ_SECONDS)

bench: build
	bash scripts/bench.sh $(BUILD_DIR)

# The container image (needs a Docker engine; CI checks its pieces without one).
image:
	docker build -f deploy/Dockerfile -t geotraj:dev .

clean:
	rm -rf $(BUILD_DIR) $(ASAN_DIR) $(TSAN_DIR) $(FUZZ_DIR) out
