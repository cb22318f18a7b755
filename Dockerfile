# edgephys relay image (the relay and the PhyS worker), the one definition of the runtime image.
# From source (compiles in a container; about 11 minutes on 2 busy cores with the base cached):
#   podman build -t localhost/edgephys-relay:0.1.0 .
# From a .deb already built (`cpack -G DEB` in a build tree; no compile, about a minute):
#   podman build --build-context deb=DIR_WITH_THE_DEB -t localhost/edgephys-relay:0.1.0 .
# (a named build context `deb` replaces the stage of that name: scripts/container.sh relay-image)
#   podman run --rm -p 7777:7777/udp -p 9464:9464 localhost/edgephys-relay:0.1.0
# Build stage: full Debian 12 toolchain and -dev packages (scripts/setup.sh is the single list).
FROM debian:bookworm AS build
ENV DEBIAN_FRONTEND=noninteractive
WORKDIR /src
# Copied alone first so the dependency layer is cached across source changes.
COPY scripts/setup.sh scripts/setup.sh
RUN EDGEPHYS_SETUP_NO_CONTAINERS=1 bash scripts/setup.sh && rm -rf /var/lib/apt/lists/*
COPY . .
# The package holds what `cmake --install` installs: the relay, the worker and the SDK.
RUN cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release -DEDGEPHYS_BUILD_TESTS=OFF \
 && cmake --build build -j2 --target edgephys-relay edgephys-phys edgephys_shared \
 && cpack --config build/CPackConfig.cmake -G DEB -B /pkg

# Stage `deb`: only edgephys_<version>_amd64.deb, at its root.
FROM scratch AS deb
COPY --from=build /pkg/edgephys_*_amd64.deb /

# Run stage: Debian's apt installs the package with its Depends (dpkg-shlibdeps: libssl3,
# spdlog, fmt, prometheus-cpp, civetweb, bullet, cpp-httplib, hiredis, ...); curl is for the
# Kubernetes preStop hook's POST /v1/drain.
FROM debian:bookworm-slim
ENV DEBIAN_FRONTEND=noninteractive
COPY --from=deb / /tmp/deb/
RUN apt-get update \
 && apt-get install -y --no-install-recommends \
      /tmp/deb/edgephys_*_amd64.deb \
      curl \
 && apt-get clean && rm -rf /var/lib/apt/lists/* /tmp/deb \
 && ln -s /usr/bin/edgephys-relay /usr/local/bin/edgephys-relay \
 && ln -s /usr/bin/edgephys-phys /usr/local/bin/edgephys-phys
# A numeric USER: Kubernetes' runAsNonRoot can only verify a numeric one (deploy/k8s uses the
# same 10001:10001).
RUN groupadd --system --gid 10001 edgephys \
 && useradd --system --uid 10001 --gid 10001 --no-create-home --home-dir /nonexistent \
      --shell /usr/sbin/nologin edgephys
# Fail the image build, not the first container start, if a runtime library is missing.
RUN for b in edgephys-relay edgephys-phys; do \
      if ldd /usr/bin/$b | grep -q 'not found'; then ldd /usr/bin/$b; exit 1; fi; \
    done
# 9465: the admin API, served only with --admin-addr 0.0.0.0:9465 and a key
# (EDGEPHYS_ADMIN_KEY); by default it listens on the container's own loopback.
EXPOSE 7777/udp 9464/tcp 9465/tcp
USER 10001:10001
ENTRYPOINT ["/usr/local/bin/edgephys-relay"]
CMD ["--bind", "0.0.0.0:7777", "--metrics", "0.0.0.0:9464"]
