# landsketch in a container: built in a Rust image, run in a slim Debian image with Mesa's
# software Vulkan driver (lavapipe), so it renders on any machine without a GPU. For a GPU
# (NVIDIA), run the same image with the NVIDIA container toolkit and
# `--gpus all -e NVIDIA_DRIVER_CAPABILITIES=graphics,compute,utility`: the toolkit mounts the
# driver's Vulkan ICD and wgpu picks the GPU over lavapipe (the log names the adapter).
# Guide: docs/src/deployment.md.

FROM rust:1-bookworm AS build
WORKDIR /src
COPY . .
RUN cargo build --release --locked --bin landsketch

FROM debian:bookworm-slim
RUN apt-get update \
 && apt-get install -y --no-install-recommends mesa-vulkan-drivers libvulkan1 ca-certificates \
 && rm -rf /var/lib/apt/lists/* \
 && useradd --system --create-home --home-dir /var/lib/landsketch landsketch \
 && install -d -m 700 -o landsketch /run/landsketch
COPY --from=build /src/target/release/landsketch /usr/local/bin/landsketch
COPY web /opt/landsketch/web
COPY data /opt/landsketch/data
WORKDIR /opt/landsketch
# Vulkan loaders want a private runtime directory.
ENV XDG_RUNTIME_DIR=/run/landsketch
USER landsketch
VOLUME /var/lib/landsketch
EXPOSE 8080
ENTRYPOINT ["landsketch", "serve"]
CMD ["--addr", "0.0.0.0:8080", "--data-dir", "/var/lib/landsketch", "--scene", "data/rbsf/scene.toml"]
