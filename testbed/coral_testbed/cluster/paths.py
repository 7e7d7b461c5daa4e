"""Files the control plane and the robots keep under their folders, named once each.

`ca_cert = Under("dir", "ca.crt")` in a class is `self.dir / "ca.crt"` when read, as a read-only
property would be, without a four-line property per file.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, overload


class Under:
    """A read-only attribute: the path `parts` below the folder the object's attribute `folder` holds."""

    def __init__(self, folder: str, *parts: str) -> None:
        self.folder = folder
        self.parts = parts

    @overload
    def __get__(self, instance: None, owner: type[Any] | None = None) -> Under: ...

    @overload
    def __get__(self, instance: object, owner: type[Any] | None = None) -> Path: ...

    def __get__(self, instance: object | None, owner: type[Any] | None = None) -> Path | Under:
        if instance is None:
            return self
        return Path(getattr(instance, self.folder)).joinpath(*self.parts)

    def __set__(self, instance: object, value: Any) -> None:
        raise AttributeError(f"{'/'.join(self.parts)} is named by its folder and cannot be set")
