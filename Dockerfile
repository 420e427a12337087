# The inertia-id service image: the API and the worker run from the same image.
FROM python:3.11-slim

ENV PYTHONDONTWRITEBYTECODE=1 PYTHONUNBUFFERED=1 PIP_NO_CACHE_DIR=1
WORKDIR /srv/inertia-id

# torch first, as the CPU build: stable-baselines3 would otherwise pull the CUDA build.
RUN pip install "torch==2.13.0" --index-url https://download.pytorch.org/whl/cpu

COPY pyproject.toml README.md ./
COPY inertia_id ./inertia_id
COPY service ./service
COPY app ./app
COPY worker ./worker
COPY frontend ./frontend
RUN pip install . && useradd --create-home --uid 1000 inertia \
    && mkdir -p /data && chown inertia /data
USER inertia
ENV INERTIA_ID_DATA_DIR=/data INERTIA_ID_FRONTEND_DIR=/srv/inertia-id/frontend

EXPOSE 8000
# The API; migrations are applied when it starts. The worker overrides the command.
# --http: uvicorn's protocol with read deadlines and request-head limits (app/request_deadlines.py).
CMD ["uvicorn", "app.main:create_app", "--factory", "--http", "app.request_deadlines:HttpToolsWithDeadlines", "--host", "0.0.0.0", "--port", "8000"]
