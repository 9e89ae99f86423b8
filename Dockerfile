# robotd's container image: `docker build -t robotd .` (docs/install.md, "Container").
#
# Two stages: the first compiles robotd with the `dist` profile (fat LTO: a long build, a
# small and fast binary), the second is a slim Debian with espeak-ng and the binary only.
# The bus is iceoryx2 shared memory in /dev/shm: run the container with a /dev/shm larger
# than Docker's 64 MB default (--shm-size=512m), or --ipc=host to share the bus with
# processes outside it. Serial ports and cameras: --device /dev/ttyUSB0 --device /dev/video0.

ARG RUST_IMAGE=rust:1-slim-bookworm
ARG RUNTIME_IMAGE=debian:bookworm-slim

FROM ${RUST_IMAGE} AS build
# iceoryx2 generates its POSIX bindings with bindgen (libclang); ring needs a C compiler.
RUN apt-get update \
    && apt-get install -y --no-install-recommends clang libclang-dev \
    && rm -rf /var/lib/apt/lists/*
WORKDIR /src
COPY . .
# PROFILE=release builds in minutes instead (no whole-program optimisation). Without the
# `bench` feature (not a default one): the service binary carries no benchmarks and no
# test-only parts.
ARG PROFILE=dist
RUN --mount=type=cache,target=/usr/local/cargo/registry \
    --mount=type=cache,target=/src/target \
    cargo build --locked --profile "${PROFILE}" --bin robotd \
    && cp "target/${PROFILE}/robotd" /usr/local/bin/robotd

FROM ${RUNTIME_IMAGE}
RUN apt-get update \
    && apt-get install -y --no-install-recommends espeak-ng ca-certificates \
    && rm -rf /var/lib/apt/lists/* \
    && useradd --system --user-group --home-dir /var/lib/robotd --shell /usr/sbin/nologin \
        --groups dialout,video,audio robotd \
    && install -d -o robotd -g robotd -m 0750 /var/lib/robotd /var/log/robotd
COPY --from=build /usr/local/bin/robotd /usr/bin/robotd
COPY packaging/robotd.toml /etc/robotd/robotd.toml
COPY config/default.toml config/niryo.toml config/widowx.toml /etc/robotd/
# The port must be reachable from outside the container, so robotd binds every interface,
# and then refuses to start without a token: pass ROBOTD_MCP__TOKEN.
ENV ROBOTD_HTTP__BIND=0.0.0.0:8000
USER robotd
WORKDIR /var/lib/robotd
VOLUME ["/var/lib/robotd", "/var/log/robotd"]
EXPOSE 8000
ENTRYPOINT ["/usr/bin/robotd", "--config", "/etc/robotd/robotd.toml"]
CMD ["serve"]
