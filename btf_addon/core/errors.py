"""Exceptions the core raises for bad input. Each message names the file and the problem."""

from __future__ import annotations


class BTFError(Exception):
    """Base class: a BTF or environment input that cannot be used as given."""


class BTFFormatError(BTFError):
    """A file is missing, truncated, corrupt or inconsistent with the rest of the material."""


class UnsupportedBTFError(BTFError):
    """A valid file that uses a feature this add-on does not implement."""
