"""Safe YAML reading that remembers the line of every key and list item.

Only :class:`yaml.SafeLoader` is used (no Python-object tags). Mappings are returned as
:class:`MarkedDict` and sequences as :class:`MarkedList`, plain ``dict``/``list`` subclasses that
carry the 1-based line number of the node and of each key / item, so that validation errors can
say where in the file a bad value is.
"""

from __future__ import annotations

import io
import re
from typing import Any

import yaml


class MarkedDict(dict):
    """A mapping from YAML with ``line`` (of the mapping) and ``key_lines`` (line of each key's value)."""

    line: int | None = None
    key_lines: dict[Any, int | None]

    def line_of(self, key: Any) -> int | None:
        return getattr(self, "key_lines", {}).get(key, self.line)


class MarkedList(list):
    """A sequence from YAML with ``line`` (of the sequence) and ``item_lines``."""

    line: int | None = None
    item_lines: list[int | None]

    def line_of(self, index: Any) -> int | None:
        lines = getattr(self, "item_lines", [])
        return lines[index] if 0 <= index < len(lines) else self.line


class DuplicateKeyError(yaml.MarkedYAMLError):
    """The same key appears twice in one mapping (plain PyYAML silently keeps the last one)."""


class _MarkedSafeLoader(yaml.SafeLoader):
    """SafeLoader whose mappings and sequences record line numbers."""


def _construct_mapping(loader: _MarkedSafeLoader, node: yaml.MappingNode) -> MarkedDict:
    loader.flatten_mapping(node)
    out = MarkedDict()
    out.line = node.start_mark.line + 1
    out.key_lines = {}
    for key_node, value_node in node.value:
        key = loader.construct_object(key_node, deep=True)
        try:
            hash(key)
        except TypeError:
            raise yaml.constructor.ConstructorError(
                "while constructing a mapping", node.start_mark, "found an unhashable key", key_node.start_mark
            ) from None
        if key in out:
            raise DuplicateKeyError(
                "while constructing a mapping",
                node.start_mark,
                f"found duplicate key {str(key)[:80]!r}",
                key_node.start_mark,
            )
        out[key] = loader.construct_object(value_node, deep=True)
        out.key_lines[key] = value_node.start_mark.line + 1
    return out


def _construct_sequence(loader: _MarkedSafeLoader, node: yaml.SequenceNode) -> MarkedList:
    out = MarkedList(loader.construct_object(child, deep=True) for child in node.value)
    out.line = node.start_mark.line + 1
    out.item_lines = [child.start_mark.line + 1 for child in node.value]
    return out


# YAML 1.1 (PyYAML) reads 1e6 and 2.0e7 as strings; scenario files are full of such numbers, so
# accept the YAML 1.2 float forms too (a sign in the exponent and the dot stay optional).
_Float12 = re.compile(r"^[-+]?(?:[0-9][0-9_]*)(?:\.[0-9_]*)?[eE][-+]?[0-9]+$|^[-+]?\.[0-9_]+[eE][-+]?[0-9]+$")
_MarkedSafeLoader.add_implicit_resolver("tag:yaml.org,2002:float", _Float12, list("-+0123456789."))
_MarkedSafeLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _construct_mapping)
_MarkedSafeLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_SEQUENCE_TAG, _construct_sequence)


class _Named(io.StringIO):
    """Text stream with a name, so that PyYAML's messages name the file."""

    def __init__(self, text: str, name: str) -> None:
        super().__init__(text)
        self.name = name


#: the most nodes a document may hold once its aliases are expanded (a scenario has a few hundred):
#: a "billion laughs" of nested aliases is refused before anything walks it
MAX_EXPANDED_NODES = 200_000


#: the longest list a document may hold (the longest frequency grid, :data:`pyfmu_wrapper.inputs.reader.MAX_GRID`)
MAX_LIST_ITEMS = 100_000


class AliasBombError(yaml.MarkedYAMLError):
    """A document whose aliases expand to more than :data:`MAX_EXPANDED_NODES` nodes."""


class TooLargeError(yaml.MarkedYAMLError):
    """A document holding a list longer than :data:`MAX_LIST_ITEMS`, or more than
    :data:`MAX_EXPANDED_NODES` values as written."""


def check_size(text: str, name: str = "<string>") -> None:
    """Refuse a document with a list of more than :data:`MAX_LIST_ITEMS` values or more than
    :data:`MAX_EXPANDED_NODES` values as written (:class:`TooLargeError`, naming the line), reading
    only up to the first value past the limit with libyaml's event parser (about 1 us a value; the
    Python composer takes some 30 us a value and all the memory of the whole tree). A document
    libyaml cannot parse is left to the Python loader and its own messages."""
    loader_cls = getattr(yaml, "CSafeLoader", None) or yaml.SafeLoader
    stack: list[list[int]] = []  # per open collection: [is a sequence, items so far, start line]
    nodes = 0
    try:
        for ev in yaml.parse(_Named(text, name), Loader=loader_cls):
            if isinstance(ev, (yaml.ScalarEvent, yaml.AliasEvent, yaml.CollectionStartEvent)):
                nodes += 1
                if stack and stack[-1][0]:
                    stack[-1][1] += 1
                    if stack[-1][1] > MAX_LIST_ITEMS:
                        line = stack[-1][2]
                        raise TooLargeError(
                            None,
                            None,
                            f"the list that starts on line {line} holds more than {MAX_LIST_ITEMS:,} values: at "
                            f"most {MAX_LIST_ITEMS:,} (a longer grid: start, stop and count)",
                            ev.start_mark,
                        )
                if nodes > MAX_EXPANDED_NODES:
                    raise TooLargeError(
                        None,
                        None,
                        f"the document holds more than {MAX_EXPANDED_NODES:,} values: refusing to read it (a "
                        "scenario holds a few hundred)",
                        ev.start_mark,
                    )
                if isinstance(ev, yaml.CollectionStartEvent):
                    stack.append([isinstance(ev, yaml.SequenceStartEvent), 0, ev.start_mark.line + 1])
            elif isinstance(ev, yaml.CollectionEndEvent) and stack:
                stack.pop()
    except TooLargeError:
        raise
    except yaml.YAMLError:
        return  # the Python loader reports it, with its own words


def expanded_size(node: yaml.Node, limit: int = MAX_EXPANDED_NODES) -> int:
    """How many nodes ``node`` stands for with every alias expanded (each shared node counted at each
    use), computed in time linear in the composed (unexpanded) graph; stops counting past ``limit``."""
    memo: dict[int, int] = {}
    order: list[yaml.Node] = []
    stack: list[tuple[yaml.Node, bool]] = [(node, False)]
    while stack:  # post-order without recursion (a deep document cannot exhaust the stack)
        n, done = stack.pop()
        if id(n) in memo:
            continue
        if done:
            kids = _children(n)
            memo[id(n)] = min(limit + 1, 1 + sum(memo[id(k)] for k in kids))
            order.append(n)
            continue
        stack.append((n, True))
        stack.extend((k, False) for k in _children(n) if id(k) not in memo)
    return memo[id(node)]


def _children(n: yaml.Node) -> list[yaml.Node]:
    if isinstance(n, yaml.SequenceNode):
        return list(n.value)
    if isinstance(n, yaml.MappingNode):
        return [x for kv in n.value for x in kv]
    return []


def load_marked(text: str, name: str = "<string>") -> Any:
    """Parse YAML text with the safe loader; mappings/lists carry line numbers.

    Aliases are allowed as long as the document they expand to holds at most
    :data:`MAX_EXPANDED_NODES` nodes (:class:`AliasBombError` otherwise, before anything is built); a
    list of more than :data:`MAX_LIST_ITEMS` values, or a document of more than
    :data:`MAX_EXPANDED_NODES` values as written, is refused first, fast (:func:`check_size`).
    Raises :class:`yaml.YAMLError` (with a ``problem_mark`` where PyYAML knows the position).
    """
    check_size(text, name)
    loader = _MarkedSafeLoader(_Named(text, name))
    try:
        node = loader.get_single_node()
        if node is None:
            return None
        n = expanded_size(node)
        if n > MAX_EXPANDED_NODES:
            raise AliasBombError(
                None,
                None,
                f"its aliases (*name) expand to more than {MAX_EXPANDED_NODES:,} values; refusing to read it "
                "(a scenario holds a few hundred: nested aliases that multiply, a 'billion laughs'?)",
                node.start_mark,
            )
        return loader.construct_document(node)
    finally:
        loader.dispose()
