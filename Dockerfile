# One image for every trajlab process (api, worker, beat, migrate); the command picks the role.
# bookworm named, not left to the tag's moving default: the PostgreSQL client below comes from PGDG's
# repository for that release.

# The user guide (/guide): MkDocs builds it from docs/, and its hook (scripts/guide_hooks.py) imports the
# app for the OpenAPI reference, so this stage installs the locked base dependencies (MkDocs and Material
# are among them, as `make install` builds the guide too), with hashes; only the built site leaves it.
FROM python:3.11-slim-bookworm AS guide
WORKDIR /srv/trajlab
ENV PYTHONDONTWRITEBYTECODE=1 NO_MKDOCS_2_WARNING=1 MPLCONFIGDIR=/tmp/matplotlib NUMBA_CACHE_DIR=/tmp/numba
COPY requirements/base.txt ./requirements/base.txt
RUN pip install --no-cache-dir --require-hashes -r requirements/base.txt
COPY pyproject.toml README.md alembic.ini mkdocs.yml ./
COPY docs ./docs
COPY examples ./examples
COPY scripts ./scripts
COPY app ./app
COPY worker ./worker
COPY solvers ./solvers
COPY migrations ./migrations
RUN mkdocs build --strict --quiet -d /guide

FROM python:3.11-slim-bookworm
WORKDIR /srv/trajlab
# NUMBA_CACHE_DIR: the read-only image cannot hold numba's compiled Lambert loop; /tmp (tmpfs) can
ENV PYTHONDONTWRITEBYTECODE=1 PYTHONUNBUFFERED=1 MPLCONFIGDIR=/tmp/matplotlib NUMBA_CACHE_DIR=/tmp/numba
# The workers compile IPOPT's derivatives to C once per problem structure (TRAJLAB_JIT=background).
# `trajlab backup`/`restore` run pg_dump, pg_restore and psql, which must be at least the server's major
# version: the client of docker-compose.yml's postgres:16, from PGDG (bookworm's own is 15, which refuses
# a 16 server). tests/unit/test_ops_files.py holds the two majors equal.
RUN apt-get update \
 && apt-get install -y --no-install-recommends gcc libc6-dev ca-certificates curl \
 && install -d /usr/share/postgresql-common/pgdg \
 && curl -fsSL -o /usr/share/postgresql-common/pgdg/apt.postgresql.org.asc \
      https://www.postgresql.org/media/keys/ACCC4CF8.asc \
 && echo "deb [signed-by=/usr/share/postgresql-common/pgdg/apt.postgresql.org.asc] https://apt.postgresql.org/pub/repos/apt bookworm-pgdg main" \
      > /etc/apt/sources.list.d/pgdg.list \
 && apt-get update \
 && apt-get install -y --no-install-recommends postgresql-client-16 \
 && apt-get purge -y curl && apt-get autoremove -y \
 && rm -rf /var/lib/apt/lists/*
# the dependencies first, from the lock (uv.lock exported with hashes: make lock), as their own layer
COPY requirements/base.txt ./requirements/base.txt
RUN pip install --no-cache-dir --require-hashes -r requirements/base.txt
COPY pyproject.toml README.md alembic.ini ./
COPY app ./app
COPY worker ./worker
COPY solvers ./solvers
COPY migrations ./migrations
# the built guide inside the package (package-data static/**/*), where app/api/routes/guide.py serves it
COPY --from=guide /guide ./app/static/guide
RUN pip install --no-cache-dir --no-deps .
# Run as an unprivileged user that owns nothing it could overwrite (the code stays root's, read-only).
RUN useradd --system --uid 10001 --no-create-home --shell /usr/sbin/nologin trajlab
RUN mkdir -p /var/cache/trajlab/jit && chown 10001:10001 /var/cache/trajlab/jit
USER 10001:10001
EXPOSE 8000
CMD ["trajlab", "api", "--host", "0.0.0.0", "--port", "8000"]
