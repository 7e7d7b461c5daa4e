"""BT.CPP's Groot2 protocol for coral.bt trees: the publisher executors run, and the Python client
`coral tree watch` and the tests use (`coral.bt.groot2.client`)."""

from coral.bt.groot2.protocol import ProtocolError
from coral.bt.groot2.publisher import DEFAULT_PORT, Groot2Publisher

__all__ = ["DEFAULT_PORT", "Groot2Publisher", "ProtocolError"]
