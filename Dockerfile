# Vigil: the dashboard in a container. Build: docker build -t vigil .
# Run:   docker run -p 8000:8000 -e VIGIL_PASSWORD=... -v vigil-data:/data vigil
FROM python:3.11-slim

ENV PYTHONDONTWRITEBYTECODE=1 \
    PYTHONUNBUFFERED=1 \
    PIP_NO_CACHE_DIR=1 \
    PIP_DISABLE_PIP_VERSION_CHECK=1 \
    VIGIL_DATA_DIR=/data \
    NUMBA_CACHE_DIR=/opt/vigil/kernels

WORKDIR /opt/vigil
COPY pyproject.toml README.md ./
COPY app ./app
COPY static ./static
COPY templates ./templates
RUN pip install . \
    && useradd --system --create-home --uid 10001 vigil \
    && mkdir -p /data /opt/vigil/kernels \
    && chown vigil /data /opt/vigil/kernels

USER 10001
# The detection kernels compiled into the image, so that a container detects from its
# first frame; on a CPU unlike the build machine's they compile (about 10 s) on first use.
RUN python -P -c "from app.vision.pipeline import warm_up; warm_up()"
VOLUME ["/data"]
EXPOSE 8000
HEALTHCHECK --interval=30s --timeout=5s CMD ["python", "-c", "import urllib.request; urllib.request.urlopen('http://127.0.0.1:8000/api/health', timeout=4)"]
ENTRYPOINT ["vigil", "serve", "--host", "0.0.0.0", "--port", "8000"]
