"""What every verdict process needs, loaded once by the fork server they start from.

:mod:`app.verdicts` starts its process through multiprocessing's ``forkserver`` with this
module as the preload: the fork server, a single-threaded process started the first time
an API process needs a verdict process, imports the core and compiles (or loads from
numba's cache) its kernels once; every verdict process is then forked from it with all of
that in memory. The first one is ready as soon as a spawned one used to be (about 3 s on
the 2-core machine); one that replaces a dead or hung child, or that a new API app in the
same process starts, is ready in a fraction of a second instead of another 3 s of imports.

Importing this module has those side effects on purpose: nothing else imports it.
"""

from __future__ import annotations

from inertia_id import warm_up
from inertia_id.classifiers import registry  # noqa: F401  (the kinds, scikit-learn)
from inertia_id.evaluation import identify  # noqa: F401
from service.store import session  # noqa: F401

from . import classifier_cache  # noqa: F401  (the cache each verdict process keeps)

warm_up()
