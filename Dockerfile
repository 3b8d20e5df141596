# phongray: the service, the command line and (with the cluster extra) Dask workers, in one image.
#
#   docker build -t phongray .                                   # from python:3.11-slim
#   docker build --build-arg BASE=phongray-base:bookworm -t phongray .   # from a base made locally (docker/build.sh)
#
# Any Debian-like base with python3 (3.11 or newer) and its venv module will do.
ARG BASE=python:3.11-slim
FROM ${BASE}

ENV PYTHONDONTWRITEBYTECODE=1 PYTHONUNBUFFERED=1 PIP_NO_CACHE_DIR=1 PATH=/opt/venv/bin:$PATH
WORKDIR /app

# bubblewrap: the sandbox students' programs run in (the container must allow user namespaces for it to start)
RUN command -v bwrap >/dev/null \
    || (apt-get update && apt-get install -y --no-install-recommends bubblewrap && rm -rf /var/lib/apt/lists/*)

# docker/ may hold pip-cert.pem, the CA bundle the building host's pip trusts (docker/build.sh puts it there)
COPY docker/ /tmp/docker/
RUN python3 -m venv /opt/venv

# Dependencies first, so that code changes do not reinstall them: install the
# project's metadata with empty packages, then replace them with the code.
COPY pyproject.toml README.md ./
RUN mkdir -p schemas tracer service bench && touch schemas/__init__.py tracer/__init__.py service/__init__.py \
        bench/__init__.py \
    && if [ -f /tmp/docker/pip-cert.pem ]; then export PIP_CERT=/tmp/docker/pip-cert.pem; fi \
    && pip install -q '.[cluster]' && pip uninstall -q -y phongray \
    && rm -rf build ./*.egg-info schemas tracer service bench  # (the build of the empty packages must not be reused)

COPY schemas ./schemas
COPY tracer ./tracer
COPY service ./service
COPY bench ./bench
COPY examples ./examples
COPY tests/scenes ./tests/scenes
RUN if [ -f /tmp/docker/pip-cert.pem ]; then export PIP_CERT=/tmp/docker/pip-cert.pem; fi \
    && pip install -q --no-deps . && rm -rf /tmp/docker && useradd --create-home --uid 10001 phongray

USER phongray
EXPOSE 8000
HEALTHCHECK --interval=30s --timeout=3s --start-period=10s --retries=3 \
    CMD python -c "import urllib.request; urllib.request.urlopen('http://127.0.0.1:8000/healthz', timeout=2)"
CMD ["phongray", "serve", "--host", "0.0.0.0", "--port", "8000", "--workers", "2"]
