"""Coral component SDK: write skillsets and drivers, declare and export their behaviors.

Public surface (stable names):
    Skillset, Driver, Component, CancelToken     -- `coral.sdk.component` (import rclpy)
    behavior, input_port, output_port, inout_port -- `coral.sdk.declaring`
    ServiceCall, LatestMessage, TopicWait, publisher -- `coral.sdk.calls` (executor side)
    ServiceBehavior                               -- `coral.sdk.behaviors` (executor side)
    run_component                                 -- `coral.sdk.running`

Names are resolved lazily so that importing `coral.sdk` for declarations does not start ROS.
"""

from __future__ import annotations

import importlib
from typing import Any

_EXPORTS = {
    "Component": "coral.sdk.component",
    "Skillset": "coral.sdk.component",
    "Driver": "coral.sdk.component",
    "CancelToken": "coral.sdk.component",
    "behavior": "coral.sdk.declaring",
    "input_port": "coral.sdk.declaring",
    "output_port": "coral.sdk.declaring",
    "inout_port": "coral.sdk.declaring",
    "ServiceCall": "coral.sdk.calls",
    "LatestMessage": "coral.sdk.calls",
    "TopicWait": "coral.sdk.calls",
    "publisher": "coral.sdk.calls",
    "ServiceBehavior": "coral.sdk.behaviors",
    "run_component": "coral.sdk.running",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'coral.sdk' has no attribute {name!r}")
    return getattr(importlib.import_module(module), name)
