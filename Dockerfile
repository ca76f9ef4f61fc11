# tcpcal: migrate, then serve. Non-root, slim base, no compilers in the final image.
FROM python:3.11-slim AS build
WORKDIR /src
COPY pyproject.toml README.md LICENSE ./
COPY app ./app
RUN python -m venv /opt/venv \
 && /opt/venv/bin/pip install --no-cache-dir --upgrade pip \
 && /opt/venv/bin/pip install --no-cache-dir .

FROM python:3.11-slim
ENV PATH=/opt/venv/bin:$PATH \
    PYTHONDONTWRITEBYTECODE=1 \
    PYTHONUNBUFFERED=1 \
    TCPCAL_DATABASE_URL=sqlite:////var/lib/tcpcal/tcpcal.sqlite3
RUN useradd --system --uid 10001 --home-dir /srv/tcpcal tcpcal \
 && mkdir -p /srv/tcpcal /var/lib/tcpcal \
 && chown tcpcal /var/lib/tcpcal
COPY --from=build /opt/venv /opt/venv
WORKDIR /srv/tcpcal
COPY alembic.ini ./
COPY migrations ./migrations
USER tcpcal
# The SQLite database (TCPCAL_DATABASE_URL above) lives here: keep it on a volume so that it
# outlives the container. With PostgreSQL (compose.yaml) nothing is written here.
VOLUME ["/var/lib/tcpcal"]
EXPOSE 8000
HEALTHCHECK --interval=30s --timeout=3s CMD python -c "import urllib.request,sys; sys.exit(urllib.request.urlopen('http://127.0.0.1:8000/health').status != 200)"
# Same two steps as `make run`: migrate, then serve (on all interfaces inside the container).
CMD ["sh", "-c", "tcpcal db upgrade && exec tcpcal serve --host 0.0.0.0 --port 8000 --workers ${TCPCAL_WORKERS:-2}"]
