"""Long flat chains (``a + b - c + ...``), which Python's parser cannot take in one piece.

:func:`ast.parse` builds a sum of a thousand terms as a left-nested tree and
gives up with a RecursionError.  The tokenizer works in a loop, so
:func:`split_chain` cuts such a text at its outermost ``+``/``-`` (or
``*``/``/``) and the parser of :mod:`hamrkq.symbolic.expressions` parses each
term on its own.
"""

from __future__ import annotations

import io
import re
import tokenize

__all__ = ["CALL", "split_chain", "wrapped"]

CALL = re.compile(r"([A-Za-z]\w*)\s*\(")


def wrapped(text: str) -> bool:
    """True when the whole of ``text`` is inside one pair of parentheses."""
    if not (text.startswith("(") and text.endswith(")")):
        return False
    depth = 0
    for index, char in enumerate(text):
        depth += {"(": 1, ")": -1}.get(char, 0)
        if depth == 0:
            return index == len(text) - 1
    return False


def split_chain(text: str) -> tuple[list[str], list[str]] | None:
    """Split ``text`` at its outermost binary ``+``/``-`` (or, failing that,
    ``*``/``/``): ``(pieces, operators)``; ``None`` when there is no such split.

    Python's :func:`ast.parse` builds ``a + b + c + ...`` as a left-nested
    tree and gives up (a RecursionError) after about a thousand terms.  The
    tokenizer works in a loop, so the text is cut into its terms here and each
    term parsed on its own.
    """
    try:
        tokens = list(tokenize.generate_tokens(io.StringIO(text).readline))
    except (tokenize.TokenError, SyntaxError, IndentationError):
        return None
    lines = text.split("\n")
    if len(lines) != 1:
        return None
    for ops in (("+", "-"), ("*", "/")):
        depth = 0
        previous = None
        cuts: list[tuple[int, int, str]] = []  # (start, end) columns of the operator
        for tok in tokens:
            if tok.type == tokenize.OP and tok.string in "([{":
                depth += 1
            elif tok.type == tokenize.OP and tok.string in ")]}":
                depth -= 1
            elif (
                depth == 0
                and tok.type == tokenize.OP
                and tok.string in ops
                and previous is not None
                and (
                    previous.type in (tokenize.NAME, tokenize.NUMBER)
                    or previous.string in (")", "]", "}")
                )
            ):
                cuts.append((tok.start[1], tok.end[1], tok.string))
            if tok.type not in (tokenize.NL, tokenize.NEWLINE, tokenize.ENDMARKER):
                previous = tok
        if cuts:
            pieces, operators, start = [], [], 0
            for begin, end, op in cuts:
                pieces.append(text[start:begin])
                operators.append(op)
                start = end
            pieces.append(text[start:])
            return pieces, operators
    return None
