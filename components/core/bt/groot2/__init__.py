"""BT.CPP's Groot2 protocol for coral_core.bt trees: the publisher executors run, and the Python client
`coral tree watch` and the tests use (`coral_core.bt.groot2.client`)."""

from coral_core.bt.groot2.protocol import ProtocolError
from coral_core.bt.groot2.publisher import DEFAULT_PORT, Groot2Publisher

__all__ = ["DEFAULT_PORT", "Groot2Publisher", "ProtocolError"]
