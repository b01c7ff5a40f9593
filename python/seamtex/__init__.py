"""seamtex - Python client of the seamtex texture service (seamtexd).

A CPython extension over libseamtex (client/seamtex.h): one ``Client`` per connection,
arrays in and out through the buffer protocol (numpy arrays when numpy is importable,
``seamtex.Array`` otherwise), server statuses raised as ``seamtex.Error`` subclasses
(``NotFound``, ``Invalid``, ``Busy``, ``TooLarge``, ...), the GIL released during every
network wait. See docs/python.md.

    >>> import seamtex, numpy as np
    >>> with seamtex.Client("127.0.0.1", 7450) as c:
    ...     values, coverage, status = c.sample("default", np.array([12], np.uint32),
    ...                                         np.array([0.98]), np.array([0.5]))
"""

from . import _seamtex
from ._seamtex import *  # noqa: F401,F403  (exception classes, Array, name lists)
from ._seamtex import Array, Error, MODES, FILTERS, FORMATS, ZERO_RULES, QSTATUS  # noqa: F401

__all__ = ["Client", "Job", "Array", "Error", "errors", "MODES", "FILTERS", "FORMATS",
           "ZERO_RULES", "QSTATUS"] + [
    n for n, v in vars(_seamtex).items()
    if isinstance(v, type) and issubclass(v, Error) and n != "Error"]
errors = _seamtex.errors
__version__ = "0.1"


class Job:
    """A compress job on the server (from ``Client.compress``).

    Attributes: ``id`` (the server's job id), ``source``, ``target``, ``client``.
    The job runs on the server whether or not anyone waits for it.
    """

    def __init__(self, client, job_id, source, target):
        self.client = client
        self.id = job_id
        self.source = source
        self.target = target

    def status(self):
        """The job's state now: dict with id, state ('queued', 'running', 'done', 'failed',
        'canceled'), progress (0..1), result (status name) and message."""
        return self.client._job_status(self.id)

    def wait(self, timeout=None):
        """Waits until the job ends; returns its status dict when done. Raises the job's
        error when it failed (e.g. ``seamtex.Unsupported``), ``seamtex.Canceled`` when it
        was cancelled, ``seamtex.TimedOut`` when ``timeout`` seconds passed first (the job
        keeps running)."""
        return self.client._job_wait(self.id, timeout)

    def cancel(self):
        """Asks the server to cancel the job; returns its status dict."""
        return self.client._job_cancel(self.id)

    def __repr__(self):
        return "<seamtex.Job %d %s -> %s>" % (self.id, self.source, self.target)


class Client(_seamtex.Client):
    __doc__ = _seamtex.Client.__doc__

    def compress(self, source, target, level=5, *, seam_aware=True, replace=False):
        """compress(source, target, level=5, *, seam_aware=True, replace=False) -> Job

        Starts BC1-compressing set ``source`` into a new set ``target`` on the server
        (seam-aware unless ``seam_aware=False``; ``level`` 0..9: 0-4 the fast encoder, 5-9
        high quality). Returns a Job: ``job.wait()``, ``job.status()``, ``job.cancel()``.
        Raises NotFound, Exists (unless ``replace=True``), Unsupported, ...
        """
        job_id = self._compress(source, target, level, seam_aware=seam_aware, replace=replace)
        return Job(self, job_id, source, target)
