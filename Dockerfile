# The try-on service: Python slim base, the package, the page's npm packages, the catalogue ingested
# at build time, a non-root user, port 8000, a health check.
FROM python:3.11-slim

ENV PYTHONDONTWRITEBYTECODE=1 \
    PYTHONUNBUFFERED=1 \
    TRYON_DATA_DIR=/app/data \
    NUMBA_CACHE_DIR=/app/.numba-cache

RUN apt-get update \
 && apt-get install -y --no-install-recommends nodejs npm curl libgomp1 \
 && rm -rf /var/lib/apt/lists/*

RUN useradd --create-home --uid 10001 tryon
WORKDIR /app

COPY pyproject.toml README.md ./
COPY server ./server
RUN pip install --no-cache-dir .

COPY web/package.json web/package-lock.json ./web/
RUN cd web && npm ci --no-audit --no-fund --no-update-notifier --loglevel=error
COPY web ./web
COPY garments ./garments

# Ingest the catalogue and compile the kernels once, at build time, so the container is ready a second or
# two after it starts and the first try-on only simulates. The numba cache is writable by the service user.
RUN mkdir -p /app/data /app/.numba-cache \
 && tryon ingest --catalogue garments/ \
 && tryon warmup \
 && chown -R tryon:tryon /app/data /app/.numba-cache

ENV TRYON_WEB_DIR=/app/web
USER tryon
EXPOSE 8000
HEALTHCHECK --interval=30s --timeout=5s --start-period=20s --retries=3 \
  CMD curl -fsS http://127.0.0.1:8000/api/health || exit 1
CMD ["tryon", "serve", "--host", "0.0.0.0", "--port", "8000"]
