# One image for the SEGB API and UI (compose runs it twice with different commands).
# Both stages use the same base, so the virtual environment built in the first runs unchanged in the second.
ARG PYTHON_IMAGE=python:3.11-slim

FROM ${PYTHON_IMAGE} AS build
ENV PIP_NO_CACHE_DIR=1 PIP_DISABLE_PIP_VERSION_CHECK=1
WORKDIR /src
# Dependencies and build tools first (pinned with hashes), so code changes do not reinstall them.
COPY requirements.lock ./
RUN python -m venv /venv && /venv/bin/pip install --require-hashes -r requirements.lock
COPY pyproject.toml setup.py README.md ./
COPY backend backend
COPY ui ui
COPY examples examples
COPY sparql sparql
COPY rules rules
# The build tools come from the lock too (setuptools): no build isolation, nothing downloaded.
RUN /venv/bin/pip install --no-deps --no-build-isolation --no-index .

FROM ${PYTHON_IMAGE}
RUN useradd --create-home --uid 10001 segb && mkdir /data && chown segb /data
COPY --from=build /venv /venv
# The SPARQL queries travel inside the installed package (segb_server/sparql); SPARQL_DIR can point elsewhere.
ENV PATH=/venv/bin:$PATH \
    PYTHONUNBUFFERED=1 \
    DATA_DIR=/data \
    HOST=0.0.0.0
WORKDIR /app
USER segb
EXPOSE 5000 8080
VOLUME ["/data"]
# The API's readiness (the store answers); compose gives the UI container a check of its own port.
HEALTHCHECK --interval=5s --timeout=3s --start-period=30s --retries=3 \
  CMD ["python", "-c", "import sys, urllib.request; sys.exit(urllib.request.urlopen('http://127.0.0.1:5000/healthz/ready', timeout=2).status != 200)"]
CMD ["segb", "serve"]
