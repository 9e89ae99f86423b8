#!/usr/bin/env bash
# The test command of robotd: ./scripts/test.sh
#
# On a fresh Debian machine with Rust and Python 3 it installs what the tests need (the
# Debian packages redis-server and espeak-ng, a Python venv in .venv with the test clients of
# tests/python/requirements.txt and requirements-nodeps.txt, and robotd's own Python package
# python/robotd, editable), then runs, in this order, stopping at the first failure:
#   cargo fmt --all -- --check
#   cargo clippy --workspace --all-targets --features bench -- -D warnings
#   cargo clippy -p robotd -- -D warnings  (the service binary alone, as a lab builds it)
#   cargo nextest run --workspace --features bench + cargo test --workspace --doc  (or cargo test --workspace
#   when cargo-nextest is not installed; nextest runs every test in its own process, which
#   keeps iceoryx2 nodes of different tests apart)
#   the real-photo tests of robotd detect, when the photos are there (REAL_IMAGES_DIR or
#   ../shared/real_images; they are not part of the repository)
#   robotd bench soak --minutes 3  (SOAK_MINUTES=N to change, 0 to skip)
# Tests that need a redis-server start their own on a free port; this script only makes sure
# the binary is there. CI runs it through .ci/run.
set -euo pipefail

cd "$(dirname "${BASH_SOURCE[0]}")/.."
ROOT="$PWD"

SCRIPT_START=$SECONDS
SECTION_START=""
section() {
    if [ -n "$SECTION_START" ]; then
        echo "    (took $((SECONDS - SECTION_START)) s)"
    fi
    SECTION_START=$SECONDS
    echo
    echo "==> $*"
}

# ------------------------------------------------------------------------------------------
section "System packages (redis-server, espeak-ng, chromium + chromedriver, python3-venv)"

missing=()
command -v redis-server >/dev/null 2>&1 || missing+=(redis-server)
command -v espeak-ng >/dev/null 2>&1 || missing+=(espeak-ng)
# The dashboard's browser test drives Debian's chromium over WebDriver.
command -v chromium >/dev/null 2>&1 || missing+=(chromium)
command -v chromedriver >/dev/null 2>&1 || missing+=(chromium-driver)
# The Debian package's test (tests/packaging_deb.rs): dpkg-shlibdeps finds the package's
# dependencies, systemd-analyze verifies its unit.
command -v dpkg-shlibdeps >/dev/null 2>&1 || missing+=(dpkg-dev)
command -v systemd-analyze >/dev/null 2>&1 || missing+=(systemd)
if ! command -v python3 >/dev/null 2>&1; then
    missing+=(python3 python3-venv)
elif ! python3 -c 'import venv, ensurepip' >/dev/null 2>&1; then
    missing+=(python3-venv)
fi

if [ "${#missing[@]}" -gt 0 ]; then
    if [ "$(id -u)" -eq 0 ]; then
        echo "installing: ${missing[*]}"
        export DEBIAN_FRONTEND=noninteractive
        apt-get update -qq
        apt-get install -y -qq --no-install-recommends "${missing[@]}"
    else
        echo "error: missing ${missing[*]}; install them with:" >&2
        echo "    sudo apt-get update && sudo apt-get install -y --no-install-recommends ${missing[*]}" >&2
        exit 1
    fi
fi
echo "redis-server: $(command -v redis-server) ($(redis-server --version | awk '{print $3}'))"
echo "espeak-ng:    $(command -v espeak-ng) ($(espeak-ng --version | head -n 1))"
echo "chromium:     $(command -v chromium) ($(chromedriver --version | awk '{print $2}'))"

for tool in cargo rustfmt cargo-clippy; do
    if ! command -v "$tool" >/dev/null 2>&1; then
        echo "error: $tool not found; install Rust with rustfmt and clippy" \
            "(rustup component add rustfmt clippy)" >&2
        exit 1
    fi
done

# cargo-deb builds the Debian package in tests/packaging_deb.rs: compiled once per machine
# (about 3 minutes on 2 cores), then kept in ~/.cargo/bin.
if ! cargo deb --version >/dev/null 2>&1; then
    echo "installing cargo-deb (cargo install --locked cargo-deb)"
    cargo install --locked --quiet cargo-deb
fi
echo "cargo-deb:    $(cargo deb --version 2>&1 | head -n 1)"

# ------------------------------------------------------------------------------------------
section "Python venv (.venv) for the test clients"

REQUIREMENTS="tests/python/requirements.txt"
# Installed without their dependencies (those are in requirements.txt): pyniryo.
REQUIREMENTS_NODEPS="tests/python/requirements-nodeps.txt"
if [ ! -x .venv/bin/python ]; then
    python3 -m venv .venv
fi
if [ -f "$REQUIREMENTS" ] && grep -qvE '^[[:space:]]*(#|$)' "$REQUIREMENTS"; then
    wanted="$(cat "$REQUIREMENTS" "$REQUIREMENTS_NODEPS" | sha256sum | cut -d' ' -f1)"
    installed="$(cat .venv/.requirements.sha256 2>/dev/null || true)"
    if [ "$wanted" != "$installed" ]; then
        .venv/bin/python -m pip install --quiet --disable-pip-version-check -r "$REQUIREMENTS"
        .venv/bin/python -m pip install --quiet --disable-pip-version-check --no-deps \
            -r "$REQUIREMENTS_NODEPS"
        echo "$wanted" > .venv/.requirements.sha256
    else
        echo "requirements unchanged, nothing to install"
    fi
else
    echo "no Python requirements to install"
fi
# The fastmcp 4.x client, in a venv of its own (fastmcp 2.x of requirements.txt stays in .venv):
# tests/mcp_camera_image.rs drives robotd with both.
REQUIREMENTS_FASTMCP4="tests/python/requirements-fastmcp4.txt"
if [ ! -x .venv-fastmcp4/bin/python ]; then
    python3 -m venv .venv-fastmcp4
fi
wanted="$(sha256sum < "$REQUIREMENTS_FASTMCP4" | cut -d' ' -f1)"
if [ "$wanted" != "$(cat .venv-fastmcp4/.requirements.sha256 2>/dev/null || true)" ]; then
    .venv-fastmcp4/bin/python -m pip install --quiet --disable-pip-version-check \
        -r "$REQUIREMENTS_FASTMCP4"
    echo "$wanted" > .venv-fastmcp4/.requirements.sha256
fi
# robotd's own Python package (python/robotd: Python actors on the bus), editable, so the tests
# run the checkout's code; its dependencies are pinned in requirements.txt.
if ! .venv/bin/python -c "import robotd, sys; sys.exit(0 if robotd.__file__.startswith('$ROOT/python/robotd/') else 1)" 2>/dev/null; then
    .venv/bin/python -m pip install --quiet --disable-pip-version-check --no-deps -e python/robotd
fi
# Tests find the venv's python (and its packages) first on PATH.
export VIRTUAL_ENV="$ROOT/.venv"
export PATH="$VIRTUAL_ENV/bin:$PATH"
echo "python: $(command -v python) ($(python --version 2>&1))"

# ------------------------------------------------------------------------------------------
export RUST_BACKTRACE="${RUST_BACKTRACE:-1}"

section "cargo fmt --all -- --check"
cargo fmt --all -- --check

# The tests drive `robotd bench`: the binary is built with its `bench` feature throughout
# (FEATURES), so clippy, the examples, the tests and the soak share one build.
FEATURES=(--features bench)

section "cargo clippy --workspace --all-targets ${FEATURES[*]} -- -D warnings"
cargo clippy --workspace --all-targets "${FEATURES[@]}" -- -D warnings

# The service binary as a lab, the .deb and the image build it: without `bench`.
section "cargo clippy -p robotd -- -D warnings"
cargo clippy -p robotd -- -D warnings

# The end-to-end tests start the example actor as a real process: build it fresh.
section "cargo build --examples"
cargo build --examples "${FEATURES[@]}"

if cargo nextest --version >/dev/null 2>&1; then
    section "cargo nextest run --workspace"
    cargo nextest run --workspace "${FEATURES[@]}" --no-fail-fast --no-tests=warn

    section "cargo test --workspace --doc"
    cargo test --workspace --doc "${FEATURES[@]}"
else
    section "cargo test --workspace (cargo-nextest not installed)"
    cargo test --workspace "${FEATURES[@]}" --no-fail-fast
fi

# The real photos are not part of the repository: their tests are #[ignore]d and run here
# when the folder is there (REAL_IMAGES_DIR, or ../shared/real_images beside the checkout).
PHOTOS="${REAL_IMAGES_DIR:-$ROOT/../shared/real_images}"
if [ -d "$PHOTOS" ]; then
    section "robotd detect on the real photos ($PHOTOS)"
    REAL_IMAGES_DIR="$PHOTOS" cargo test --quiet "${FEATURES[@]}" --test cli_detect -- --ignored
fi

# The soak: the service under a realistic mix with faults, for SOAK_MINUTES (3 by default;
# SOAK_MINUTES=0 skips it). Fails on memory, descriptors or threads growing, a fault not
# recovered, or a call without an answer.
SOAK_MINUTES="${SOAK_MINUTES:-3}"
if [ "$SOAK_MINUTES" != "0" ]; then
    section "robotd bench soak --minutes $SOAK_MINUTES"
    cargo run --quiet "${FEATURES[@]}" -- bench soak --minutes "$SOAK_MINUTES"
fi

section "done"
echo "all checks passed in $((SECONDS - SCRIPT_START)) s"
