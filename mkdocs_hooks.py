"""MkDocs hooks: render the few reStructuredText constructs of abkit's
numpydoc docstrings that mkdocstrings (Markdown) leaves as text.

- Sphinx roles ``:func:`x``` (also class, meth, data, mod, attr, obj) -> ``x``;
- ``.. math::`` + indented block -> display math (MathJax);
- ``.. code-block:: text`` + indented block -> the code block alone.
"""

from __future__ import annotations

import re
from typing import Any

_ROLE = re.compile(r":(?:func|class|meth|data|mod|attr|obj|exc):(<code>)")
_MATH = re.compile(
    r'<p>\.\. math::</p>\s*<div class="highlight"><pre><span></span><code>(.*?)</code></pre></div>', re.S
)
_CODE = re.compile(r"<p>\.\. code-block::\s*\w*</p>\s*")


def on_page_content(html: str, **kwargs: Any) -> str:
    html = _ROLE.sub(r"\1", html)
    html = _MATH.sub(lambda m: '<div class="arithmatex">\\[' + m.group(1).strip() + "\\]</div>", html)
    return _CODE.sub("", html)
