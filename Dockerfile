# Linkage topology service: uvicorn on 0.0.0.0:8000 as a non-root user.
#
# Base: the official python:3.11-slim (Python 3.11.15, Debian trixie), pinned by the digest of
# its multi-platform index as published by Docker's official-images tooling in
# docker-library/repo-info (repos/python/remote/3.11-slim.md, August 2026). To move to a newer
# base, take the digest from that file (or `docker buildx imagetools inspect python:3.11-slim`).
FROM python:3.11-slim@sha256:90744cff8f32887f075c47d747a173ff333e9e98801667af93c357fa9f5e28ff

ENV PYTHONDONTWRITEBYTECODE=1 \
    PYTHONUNBUFFERED=1 \
    PIP_NO_CACHE_DIR=1 \
    PIP_DISABLE_PIP_VERSION_CHECK=1

RUN useradd --create-home --uid 10001 --shell /usr/sbin/nologin app
WORKDIR /app

# Dependencies first, pinned and hashed (scripts/lock.sh writes requirements.lock): this layer
# is rebuilt only when the lock changes, not on every change of the code.
COPY requirements.lock ./
RUN pip install --require-hashes --no-deps -r requirements.lock

# The code, without dependencies (all in the layer above) and built with the base image's
# setuptools (no download).
COPY pyproject.toml README.md ./
COPY engine ./engine
COPY service ./service
RUN pip install --no-deps --no-build-isolation .

# The tracer's compiled kernel (numba, engine/space/trace_kernel.py; and the closed form's,
# engine/space/dyads/kernel.py) compiled once here, into a cache
# handed to the app user: a new container traces compiled from its first request instead of on
# the Python loop for the 20-30 s a cold compile takes.
ENV NUMBA_CACHE_DIR=/home/app/.cache/numba
RUN python -c "from engine.space import trace_kernel; assert trace_kernel.load(), trace_kernel.failure" \
    && python -c "from engine.space.dyads import kernel; assert kernel.load(), kernel.failure" \
    && chown -R app:app /home/app/.cache

USER app
EXPOSE 8000
# Healthy = ready (/health/ready): the kernels are loaded and the engine workers answer; a
# worker pool that breaks is replaced within a second, and one that cannot be replaced makes
# the container unhealthy. The start period covers a cold start on a loaded machine.
HEALTHCHECK --interval=15s --timeout=5s --start-period=120s --retries=3 \
    CMD ["python", "-c", "import sys, urllib.request; sys.exit(0 if urllib.request.urlopen('http://127.0.0.1:8000/health/ready', timeout=4).status == 200 else 1)"]
# LINKAGE_WORKERS defaults to the container's CPU quota (docker run --cpus) when it is smaller
# than the host's cores. --proxy-headers trusts X-Forwarded-For/-Proto only from the addresses
# in FORWARDED_ALLOW_IPS (default 127.0.0.1): set it to the reverse proxy's address. The JSON
# access log (stdout) replaces uvicorn's plain one.
CMD ["uvicorn", "service.main:app", "--host", "0.0.0.0", "--port", "8000", \
     "--http", "service.protocol:GuardedH11Protocol", "--proxy-headers", "--no-access-log"]
