"""YAML as trackfw reads it: ``yaml.safe_load`` semantics, bounded and strict.

A document whose aliases expand past :data:`MAX_YAML_VALUES` values is refused before any Python
object is built, and :func:`parse_yaml` also rejects duplicate mapping keys and turns every YAML
error into one ``FILE: line L, column C: ...`` :class:`~trackfw.errors.UserError`.
"""

from __future__ import annotations

from typing import Any

import yaml

from trackfw.errors import UserError, quoted

#: Most values (scalars, lists, mappings) a YAML document may stand for once its aliases are
#: expanded. A pipeline has a few hundred; nine nested lists of nine aliases (a "billion laughs"
#: bomb) stand for hundreds of millions, which everything downstream (copying, hashing, error
#: messages) would walk.
MAX_YAML_VALUES = 100_000


class YamlTooLargeError(yaml.composer.ComposerError):
    """A YAML document whose aliases expand to more than :data:`MAX_YAML_VALUES` values."""


def _expanded_size(root: yaml.Node, limit: int) -> int:
    """Values ``root`` stands for with every alias expanded, counting up to just over ``limit``.

    Aliases share node objects, so each distinct node's size is computed once; the walk never
    expands anything. A node that contains itself (a recursive alias) counts as over the limit.
    """
    sizes: dict[int, int] = {}
    open_nodes: set[int] = set()

    def size(node: yaml.Node) -> int:
        key = id(node)
        if key in sizes:
            return sizes[key]
        if key in open_nodes:
            return limit + 1
        open_nodes.add(key)
        total = 1
        if isinstance(node, yaml.SequenceNode):
            for child in node.value:
                total += size(child)
                if total > limit:
                    break
        elif isinstance(node, yaml.MappingNode):
            for key_node, value_node in node.value:
                total += size(key_node) + size(value_node)
                if total > limit:
                    break
        open_nodes.discard(key)
        sizes[key] = min(total, limit + 1)
        return sizes[key]

    return size(root)


class _BoundedLoader(yaml.SafeLoader):
    """SafeLoader that refuses documents whose aliases expand beyond :data:`MAX_YAML_VALUES`.

    The check runs on the composed node graph, before any Python object is built.
    """

    def compose_document(self) -> yaml.Node | None:
        node = super().compose_document()
        if node is not None and _expanded_size(node, MAX_YAML_VALUES) > MAX_YAML_VALUES:
            raise YamlTooLargeError(
                None,
                None,
                f"the document stands for more than {MAX_YAML_VALUES} values once its aliases"
                " are expanded (an alias bomb?); expected plain data",
                node.start_mark,
            )
        return node


def safe_load(text: str) -> Any:
    """``yaml.safe_load`` with the alias-expansion bound of :class:`_BoundedLoader`."""
    loader = _BoundedLoader(text)
    try:
        return loader.get_single_data()
    finally:
        loader.dispose()


class _StrictLoader(_BoundedLoader):
    """Bounded SafeLoader that rejects duplicate mapping keys instead of keeping the last one."""


def _construct_mapping(
    loader: _StrictLoader, node: yaml.MappingNode, deep: bool = False
) -> dict[Any, Any]:
    seen: dict[Any, int] = {}
    for key_node, _ in node.value:
        key = loader.construct_object(key_node, deep=deep)
        if key in seen:
            raise yaml.constructor.ConstructorError(
                None,
                None,
                f"duplicate key {quoted(key)} (first on line {seen[key] + 1})",
                key_node.start_mark,
            )
        seen[key] = key_node.start_mark.line
    return dict(yaml.SafeLoader.construct_mapping(loader, node, deep=deep))


_StrictLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _construct_mapping)


def parse_yaml(text: str, source: str) -> Any:
    """Parse YAML safely; duplicate keys and syntax errors become one-line UserErrors."""
    loader = _StrictLoader(text)
    try:
        return loader.get_single_data()
    except yaml.MarkedYAMLError as error:
        mark = error.problem_mark
        where = f"line {mark.line + 1}, column {mark.column + 1}: " if mark is not None else ""
        raise UserError(f"{source}: {where}invalid YAML: {error.problem}.") from None
    except yaml.YAMLError as error:
        raise UserError(f"{source}: invalid YAML: {error}.") from None
    finally:
        loader.dispose()
