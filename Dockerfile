# edgephys relay image.
#   docker build -t edgephys-relay .
#   docker run --rm -p 7777:7777/udp -p 9464:9464 edgephys-relay
# Build stage: full Debian 12 toolchain and -dev packages (scripts/setup.sh is the single list).
FROM debian:bookworm AS build
ENV DEBIAN_FRONTEND=noninteractive
WORKDIR /src
# Copied alone first so the dependency layer is cached across source changes.
COPY scripts/setup.sh scripts/setup.sh
RUN EDGEPHYS_SETUP_NO_CONTAINERS=1 bash scripts/setup.sh && rm -rf /var/lib/apt/lists/*
COPY . .
RUN cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release -DEDGEPHYS_BUILD_TESTS=OFF \
 && cmake --build build -j2 --target edgephys-relay edgephys-phys

# Run stage: only the shared libraries the relay loads (from `ldd edgephys-relay` + `dpkg -S`).
#   libssl3                                      libcrypto.so.3 (tokens, cookies)
#   libspdlog1.10, libfmt9                       logging (Debian's spdlog uses the shared fmt)
#   libprometheus-cpp-core1.0, libprometheus-cpp-pull1.0, libcivetweb1   /metrics server
#   libbullet3.24                                PhyS (embedded in the relay, and edgephys-phys)
#   libcpp-httplib0.11                           the admin API (docs/admin-api.md)
#   libhiredis0.14                               --redis (clusters of relays)
#   curl                                         the Kubernetes preStop hook's POST /v1/drain
# libstdc++6, libgcc-s1, libc6 and zlib1g are already in bookworm-slim. FlatBuffers, Asio,
# CLI11 and Eigen are header-only here.
FROM debian:bookworm-slim
ENV DEBIAN_FRONTEND=noninteractive
RUN apt-get update \
 && apt-get install -y --no-install-recommends \
      libssl3 \
      libspdlog1.10 \
      libfmt9 \
      libprometheus-cpp-core1.0 \
      libprometheus-cpp-pull1.0 \
      libcivetweb1 \
      libbullet3.24 \
      libcpp-httplib0.11 \
      libhiredis0.14 \
      curl \
 && rm -rf /var/lib/apt/lists/*
# A numeric USER: Kubernetes' runAsNonRoot can only verify a numeric one (deploy/k8s uses the
# same 10001:10001).
RUN groupadd --system --gid 10001 edgephys \
 && useradd --system --uid 10001 --gid 10001 --no-create-home --home-dir /nonexistent \
      --shell /usr/sbin/nologin edgephys
COPY --from=build /src/build/relay/edgephys-relay /usr/local/bin/edgephys-relay
# The remote PhyS worker ships in the same image: `--entrypoint edgephys-phys`.
COPY --from=build /src/build/physics_backend/edgephys-phys /usr/local/bin/edgephys-phys
# Fail the image build, not the first container start, if a runtime library is missing.
RUN for b in edgephys-relay edgephys-phys; do \
      if ldd /usr/local/bin/$b | grep -q 'not found'; then ldd /usr/local/bin/$b; exit 1; fi; \
    done
# 9465: the admin API, served only with --admin-addr 0.0.0.0:9465 and a key
# (EDGEPHYS_ADMIN_KEY); by default it listens on the container's own loopback.
EXPOSE 7777/udp 9464/tcp 9465/tcp
USER 10001:10001
ENTRYPOINT ["/usr/local/bin/edgephys-relay"]
CMD ["--bind", "0.0.0.0:7777", "--metrics", "0.0.0.0:9464"]
