"""The core's one error type for bad input.

:class:`InputError` means the caller's input broke a rule (a scenario that is not
physical, a sequence with a level out of range, telemetry that does not cover the
sequence, an unknown option, a damaged document); its message names the rule and quotes
the value. It is a ``ValueError``, so code that caught ``ValueError`` still catches it.
A pydantic model validated from data (a scenario, telemetry) refuses it with pydantic's
``ValidationError``, a ``ValueError`` too, its entries naming the fields. Anything else
the core raises is a defect, not the caller's fault.
"""

from __future__ import annotations

__all__ = ["InputError"]


class InputError(ValueError):
    """The caller's input broke a rule; the message says which and quotes the value."""
