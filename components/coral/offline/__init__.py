"""The robot's offline agent: records the last revision the robot ran, runs it as static pods when
the robot boots without the API server, and hands over to the API server's pods (docs/offline.md)."""
