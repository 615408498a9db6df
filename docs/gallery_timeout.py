"""A time limit per tutorial in the docs build (sphinx-gallery has none of its own).

sphinx-gallery runs the tutorials one after another in the build's own process and calls its
``reset_modules`` callables before and after each one; :func:`limit_time` is one of them. It
arms two clocks when a tutorial starts and disarms them when it ends:

* at the limit, [s] (``HYDROLINE_DOCS_TUTORIAL_TIMEOUT``, default :data:`DEFAULT_LIMIT`;
  0 switches the limit off) a :class:`TutorialTimeout` is raised in the tutorial's code,
  naming it: sphinx-gallery reports it as that tutorial's error and the build fails;
* :data:`GRACE` seconds later, if the tutorial is still running (stuck inside compiled code,
  where Python cannot raise), the process is ended with every thread's traceback on stderr
  (:func:`faulthandler.dump_traceback_later`; the tutorial's file is in the traceback).
"""
from __future__ import annotations

import faulthandler
import os
import signal
import threading
from pathlib import Path

#: Longest a tutorial may run in the docs build, [s]: about five times the slowest tutorial's
#: time (tutorial d, control design: 114 s on two cores shared with other jobs, 2026).
DEFAULT_LIMIT = 600.0
#: Time after the limit at which a tutorial that did not stop is ended with the process, [s].
GRACE = 60.0
#: Environment variable that sets the limit, [s].
ENVIRONMENT = "HYDROLINE_DOCS_TUTORIAL_TIMEOUT"


class TutorialTimeout(Exception):
    """A tutorial that ran past the docs build's limit.

    Parameters
    ----------
    *args : str
        The message: one line naming the tutorial, the limit and how to change it
    """


def time_limit() -> float:
    """The limit per tutorial, [s] (0: none), from :data:`ENVIRONMENT`.

    Returns
    -------
    float
        Seconds a tutorial may run, [s]; 0 for no limit

    Raises
    ------
    ValueError
        One line naming the environment variable, for a value that is no number >= 0
    """
    text = os.environ.get(ENVIRONMENT, "").strip()
    if not text:
        return DEFAULT_LIMIT
    try:
        value = float(text)
    except ValueError:
        value = -1.0
    if not value >= 0:
        raise ValueError(f"{ENVIRONMENT}: expected seconds >= 0 (0: no limit), got {text!r}")
    return value


def limit_time(gallery_conf, fname, when):
    """Arm (``when == "before"``) or disarm (``"after"``) the limit of one tutorial.

    Parameters
    ----------
    gallery_conf : dict
        sphinx-gallery's configuration (not used)
    fname : str or None
        The tutorial about to run or just run; None when a gallery directory is entered
    when : str
        ``"before"`` or ``"after"`` the tutorial
    """
    if hasattr(signal, "SIGALRM") and threading.current_thread() is threading.main_thread():
        signal.setitimer(signal.ITIMER_REAL, 0.0)
    faulthandler.cancel_dump_traceback_later()
    limit = time_limit()
    if when != "before" or fname is None or limit == 0:
        return
    name = Path(fname).name
    message = (f"{name}: ran past the docs build's limit of {limit:g} s per tutorial "
               f"({ENVIRONMENT}=seconds to change it, 0 for none)")
    if hasattr(signal, "SIGALRM") and threading.current_thread() is threading.main_thread():
        def stop(signum, frame):
            signal.setitimer(signal.ITIMER_REAL, 0.0)
            raise TutorialTimeout(message)

        signal.signal(signal.SIGALRM, stop)
        signal.setitimer(signal.ITIMER_REAL, limit)
    # the last resort, for a tutorial stuck where no exception reaches it (compiled code that
    # holds on): the process ends with every thread's traceback, the tutorial's file among them
    faulthandler.dump_traceback_later(limit + GRACE, exit=True)
