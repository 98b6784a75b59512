# One image for every trajlab process (api, worker, beat, migrate); the command picks the role.
FROM python:3.11-slim
WORKDIR /srv/trajlab
# NUMBA_CACHE_DIR: the read-only image cannot hold numba's compiled Lambert loop; /tmp (tmpfs) can
ENV PYTHONDONTWRITEBYTECODE=1 PYTHONUNBUFFERED=1 MPLCONFIGDIR=/tmp/matplotlib NUMBA_CACHE_DIR=/tmp/numba
# the dependencies first, from the lock (uv.lock exported with hashes: make lock), as their own layer
COPY requirements/base.txt ./requirements/base.txt
RUN pip install --no-cache-dir --require-hashes -r requirements/base.txt
COPY pyproject.toml README.md alembic.ini ./
COPY app ./app
COPY worker ./worker
COPY solvers ./solvers
COPY migrations ./migrations
RUN pip install --no-cache-dir --no-deps .
# The workers compile IPOPT's derivatives to C once per problem structure (TRAJLAB_JIT=background).
RUN apt-get update && apt-get install -y --no-install-recommends gcc libc6-dev && rm -rf /var/lib/apt/lists/*
# Run as an unprivileged user that owns nothing it could overwrite (the code stays root's, read-only).
RUN useradd --system --uid 10001 --no-create-home --shell /usr/sbin/nologin trajlab
RUN mkdir -p /var/cache/trajlab/jit && chown 10001:10001 /var/cache/trajlab/jit
USER 10001:10001
EXPOSE 8000
CMD ["trajlab", "api", "--host", "0.0.0.0", "--port", "8000"]
