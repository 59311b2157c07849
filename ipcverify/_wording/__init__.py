"""The wording layer: how a parameter, a remedy or a verdict is said, to Python users and on the CLI.

Library code states facts -- numbers, enums and typed remedies
(:class:`~ipcverify._wording._spelling.Remedy`: which parameter, what value) -- and never spells a
command-line flag or words a verdict itself. This package is the one place that does:

* :mod:`~ipcverify._wording._audience` -- who reads the running code's messages: a Python caller
  (the default) or a command-line user (while a CLI command runs, :func:`speaking`);
* :mod:`~ipcverify._wording._spelling` -- every parameter and command a message may name, with
  its Python and its CLI spelling, and the renderers (``option``, ``render``, ``command``);
* :mod:`~ipcverify._wording._verdicts` -- the verdicts of a certificate (its status, Theorem 1,
  the domain of validity, the test that was not run), each worded by one function from plain
  facts, and called by the summary, the CLI's table and the HTML page alike.

Every layer of ipcverify imports it, so it imports nothing from ipcverify: callers pass plain
facts (numbers, strings), never their records. Modules import from the defining module
(``from ipcverify._wording._spelling import option``); this package exports nothing.
"""

from __future__ import annotations

__all__: list[str] = []
