# hilnav service image: the `hilnav` console script (sim, fusion, monitor, up, ...).
#
#   docker build -t hilnav:local .
#   docker run --rm hilnav:local list
#
# docker-compose.yml runs one container per service from this image.

FROM python:3.11-slim-bookworm

ENV PYTHONDONTWRITEBYTECODE=1 \
    PYTHONUNBUFFERED=1 \
    PIP_NO_CACHE_DIR=1 \
    PIP_DISABLE_PIP_VERSION_CHECK=1

WORKDIR /src
# a C compiler for the compiled kernels (fusion/_strapdown.c, fusion/_update.c,
# sim/_simkernel.c; docs/development.md, "Compiled kernels");
# without it pip would silently install the slower, bit-identical Python references only
RUN apt-get update \
    && apt-get install -y --no-install-recommends gcc libc6-dev \
    && rm -rf /var/lib/apt/lists/*
# the package sources only (no tests, benches, outputs); the wheels of jsbsim, eclipse-zenoh,
# numpy, scipy... come from PyPI, the aircraft data ships inside the jsbsim wheel
COPY pyproject.toml setup.py README.md ./
COPY sim ./sim
COPY hil ./hil
COPY fusion ./fusion
COPY scenarios ./scenarios
COPY physconst ./physconst
RUN pip install . \
    && (cd / && python -c "import fusion._strapdown, fusion._update, sim._simkernel") \
    && useradd --create-home --uid 10001 hilnav \
    && mkdir -p /data \
    && chown hilnav /data

# run from the home folder so `python -m hil.bus` imports the installed package
USER hilnav
WORKDIR /home/hilnav

# MAVLink in (fusion: udpin:0.0.0.0:14560)
EXPOSE 14560/udp

ENTRYPOINT ["hilnav"]
CMD ["--help"]
