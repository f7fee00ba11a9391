"""Where a TOML text nests arrays and inline tables deepest: the table, key and line (standard library only).

``tomllib`` parses nested arrays by recursion, so a file nesting thousands of them deep ends in Python's
``RecursionError`` rather than a ``TOMLDecodeError`` with a line. :func:`deepest` finds the place by a scan
that needs no recursion (comments and strings skipped, table headers followed), so that the rig file's
refusal can name the table and the key (``helpers.rigfile.model``).
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["Nesting", "deepest"]


@dataclass(frozen=True)
class Nesting:
    """The deepest nesting of a TOML text.

    ``depth`` brackets open at ``line`` (1-based), in ``table`` (e.g. ``[arm]``, ``[[tendon]] #2``; empty at
    the top level) under ``key`` (as written before its ``=``).
    """

    depth: int
    line: int
    table: str
    key: str

    @property
    def where(self) -> str:
        """``[table] key`` (the key alone at the top level)."""
        return f"{self.table} {self.key}".strip()


def _string_end(text: str, i: int) -> int:
    """The index after the string starting at ``text[i]`` (basic or literal, one line or multi-line)."""
    quote = text[i]
    delim = quote * 3 if text.startswith(quote * 3, i) else quote
    j = i + len(delim)
    while j < len(text):
        if quote == '"' and text[j] == "\\":
            j += 2
            continue
        if text.startswith(delim, j):
            return j + len(delim)
        if len(delim) == 1 and text[j] == "\n":
            return j  # an unterminated one-line string: tomllib reports it; stop at the line's end
        j += 1
    return j


def deepest(text: str) -> Nesting:
    """The deepest nesting of arrays and inline tables in ``text`` (the first place it is reached)."""
    best = Nesting(0, 0, "", "")
    depth, line, table, tendons, key = 0, 1, "", 0, ""
    key_start, line_start = 0, True
    i, n = 0, len(text)
    while i < n:
        c = text[i]
        if c == "\n":
            line += 1
            if depth == 0:
                line_start, key_start = True, i + 1
            i += 1
        elif c in " \t\r":
            i += 1
        elif c == "#":
            end = text.find("\n", i)
            i = n if end < 0 else end
        elif c in "\"'":
            end = _string_end(text, i)
            line += text.count("\n", i, end)
            i, line_start = end, False
        elif c == "[" and depth == 0 and line_start:  # a table header: [name] or [[name]]
            end = text.find("\n", i)
            header = text[i : n if end < 0 else end].split("#")[0].strip()
            if header.replace(" ", "") == "[[tendon]]":
                tendons += 1
                table = f"[[tendon]] #{tendons}"
            else:
                table = header
            i = n if end < 0 else end
        else:
            line_start = False
            if c == "=" and depth == 0:
                key = text[key_start:i].strip()
            elif c in "[{":
                depth += 1
                if depth > best.depth:
                    best = Nesting(depth, line, table, key)
            elif c in "]}":
                depth = max(0, depth - 1)
            i += 1
    return best
