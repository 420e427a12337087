"""HTTP routers, one per resource."""

from . import auth, classifiers, health, identify, jobs, scenarios, vocabulary

__all__ = ["ROUTERS"]

ROUTERS = (
    scenarios.router,
    jobs.router,
    classifiers.router,
    identify.router,
    health.router,
    vocabulary.router,
    auth.router,
)
