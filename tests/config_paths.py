"""Every place in a scenario's YAML tree where a fuzzing test can put an odd value."""

from __future__ import annotations


def value_paths(node, prefix=()):
    """Every place a value can be replaced: keys of mappings (sections too) and list elements."""
    if isinstance(node, dict):
        for k, v in node.items():
            yield prefix + (k,)
            yield from value_paths(v, prefix + (k,))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            yield prefix + (i,)
            yield from value_paths(v, prefix + (i,))
