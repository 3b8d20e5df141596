# phongray service: a slim image serving on port 8000 as a non-root user.
FROM python:3.11-slim

ENV PYTHONDONTWRITEBYTECODE=1 PYTHONUNBUFFERED=1 PIP_NO_CACHE_DIR=1
WORKDIR /app

# Dependencies first, so that code changes do not reinstall them: install the
# project's metadata with empty packages, then replace them with the code.
COPY pyproject.toml README.md ./
RUN mkdir -p schemas tracer service && touch schemas/__init__.py tracer/__init__.py service/__init__.py \
    && pip install . && pip uninstall -y phongray

COPY schemas ./schemas
COPY tracer ./tracer
COPY service ./service
RUN pip install --no-deps . && useradd --create-home --uid 10001 phongray

USER phongray
EXPOSE 8000
HEALTHCHECK --interval=30s --timeout=3s --start-period=10s --retries=3 \
    CMD python -c "import urllib.request; urllib.request.urlopen('http://127.0.0.1:8000/healthz', timeout=2)"
CMD ["phongray", "serve", "--host", "0.0.0.0", "--port", "8000", "--workers", "2"]
