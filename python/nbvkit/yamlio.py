"""YAML as nbvkit reads it: numbers such as 1e-4 read as numbers (YAML 1.2), a document's size
bounded through its aliases (a "billion laughs" is refused), a key given twice in one mapping
refused (PyYAML keeps the last silently), errors naming the file and line."""
from __future__ import annotations

import re

import yaml

from .limits import MAX_TEXT_FILE_BYTES, MAX_YAML_NODES, check_input_file, shorten


class YamlLoader(yaml.SafeLoader):
    """PyYAML's safe loader with YAML 1.2's numbers: 1e-4 / 2E5 are numbers (PyYAML's YAML 1.1
    resolver wants a dot and a signed exponent, and reads 1e-4 as a string), 010 is ten (YAML
    1.1: eight, octal; 0o10 is eight) and 1:30 a string (YAML 1.1: 90, base 60)."""


_INT, _FLOAT = "tag:yaml.org,2002:int", "tag:yaml.org,2002:float"
YamlLoader.yaml_implicit_resolvers = {
    first: [(tag, rx) for tag, rx in resolvers if tag not in (_INT, _FLOAT)]
    for first, resolvers in yaml.SafeLoader.yaml_implicit_resolvers.items()
}
YamlLoader.add_implicit_resolver(
    _INT,
    re.compile(r"^(?:[-+]?[0-9][0-9_]*|0x[0-9a-fA-F_]+|0o[0-7_]+)$"),
    list("-+0123456789"),
)
YamlLoader.add_implicit_resolver(
    _FLOAT,
    re.compile(
        r"^(?:[-+]?(?:[0-9][0-9_]*\.[0-9_]*|\.[0-9_]+)(?:[eE][-+]?[0-9]+)?"
        r"|[-+]?[0-9][0-9_]*[eE][-+]?[0-9]+|[-+]?\.(?:inf|Inf|INF)|\.(?:nan|NaN|NAN))$"
    ),
    list("-+0123456789."),
)


def _construct_int(loader: YamlLoader, node) -> int:
    """An int as YAML 1.2 reads it: decimal (leading zeros too), 0x hexadecimal, 0o octal."""
    text = loader.construct_scalar(node).replace("_", "")
    sign = -1 if text.startswith("-") else 1
    body = text.lstrip("+-")
    base = {"0x": 16, "0o": 8}.get(body[:2], 10)
    return sign * int(body[2:] if base != 10 else body, base)


YamlLoader.add_constructor(_INT, _construct_int)


def _expanded_nodes(node, limit: int, memo: dict) -> int:
    """Nodes of a composed YAML document once its aliases are expanded (an alias repeats its
    anchor's whole subtree); stops counting past `limit`."""
    key = id(node)
    if key in memo:
        return memo[key]
    memo[key] = limit + 1  # a node reached again while being counted: a cycle
    n = 1
    if isinstance(node, yaml.SequenceNode):
        children = node.value
    elif isinstance(node, yaml.MappingNode):
        children = [x for pair in node.value for x in pair]
    else:
        children = []
    for child in children:
        n += _expanded_nodes(child, limit, memo)
        if n > limit:
            break
    memo[key] = n
    return n


_MERGE = "tag:yaml.org,2002:merge"


def _duplicate_key(loader: YamlLoader, root, source: str) -> str | None:
    """The message ("source:LINE: duplicate key ...") of a mapping of the composed document
    `root` that gives a key twice (keys compared as constructed: 'a' and "a" are one), or None.
    Merge keys' entries (``<<: *base``) are not compared: the mapping's own keys override them."""
    seen_nodes, stack = set(), [root]
    while stack:
        node = stack.pop()
        if id(node) in seen_nodes:
            continue
        seen_nodes.add(id(node))
        if isinstance(node, yaml.SequenceNode):
            stack.extend(node.value)
        elif isinstance(node, yaml.MappingNode):
            first: dict = {}
            for key_node, value_node in node.value:
                stack.extend((key_node, value_node))
                if not isinstance(key_node, yaml.ScalarNode) or key_node.tag == _MERGE:
                    continue
                key = loader.construct_object(key_node)
                try:
                    was = first.setdefault(key, key_node)
                except TypeError:  # an unhashable key: the constructor names it
                    continue
                if was is not key_node:
                    return (
                        f"{source}:{key_node.start_mark.line + 1}: duplicate key "
                        f"{shorten(key)} (first given on line {was.start_mark.line + 1}); "
                        "give each key once"
                    )
    return None


def parse_yaml(text: str, source: str = "<string>"):
    """YAML text parsed with YamlLoader; ValueError "source:line: problem" on a syntax error, a key
    given twice in one mapping (at any depth), and for a document whose aliases expand to more
    than MAX_YAML_NODES nodes (a "billion laughs")."""
    try:
        loader = YamlLoader(text)
        try:
            node = loader.get_single_node()
            if node is not None and _expanded_nodes(node, MAX_YAML_NODES, {}) > MAX_YAML_NODES:
                raise ValueError(
                    f"{source}: the YAML document expands (through its aliases) to more than "
                    f"{MAX_YAML_NODES:,} values, the limit of a configuration"
                )
            duplicate = None if node is None else _duplicate_key(loader, node, source)
            if duplicate is not None:
                raise ValueError(duplicate)
            return loader.construct_document(node) if node is not None else None
        finally:
            loader.dispose()
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None) or getattr(e, "context_mark", None)
        where = f"{source}:{mark.line + 1}" if mark is not None else source
        problem = getattr(e, "problem", None) or str(e).splitlines()[0]
        raise ValueError(f"{where}: {shorten(problem, 200)}") from None
    except RecursionError:
        raise ValueError(f"{source}: the YAML document is nested too deeply") from None
    except ValueError as e:  # PyYAML's own int(): a number of over 4,300 digits
        if str(e).startswith(source):
            raise
        raise ValueError(f"{source}: {shorten(str(e), 200)}") from None


def read_yaml_file(path, what: str = "YAML file"):
    """A YAML file parsed (see parse_yaml); FileNotFoundError for a missing path, ValueError
    naming the file for anything but a regular file of at most MAX_TEXT_FILE_BYTES (a directory,
    a FIFO, a device), undecodable text or a syntax error."""
    p = check_input_file(path, what, MAX_TEXT_FILE_BYTES)
    try:
        text = p.read_text()
    except (OSError, UnicodeDecodeError) as e:
        raise ValueError(f"cannot read {what} {p}: {shorten(str(e), 200)}") from None
    return parse_yaml(text, str(p))


def read_yaml_mapping(path, what: str, empty_hint: str) -> dict:
    """read_yaml_file of a file that must hold a mapping of keys: ValueError naming the file if
    it holds something else, or nothing (a wrong or truncated file, not the defaults taken in its
    place; `empty_hint` says what to write instead)."""
    data = read_yaml_file(path, what)
    if data is None:
        raise ValueError(f"{what} {path} is empty ({empty_hint})")
    if not isinstance(data, dict):
        raise ValueError(f"{what} {path} must hold a mapping of keys, got {type(data).__name__}")
    return data
