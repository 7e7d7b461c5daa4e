"""A scraper standing in for Prometheus: it fetches the operator's `/metrics` at a fixed interval
(Prometheus's default is 1 min, prometheus-operator's ServiceMonitors often 30 s; the benchmark
scrapes more often than either) and counts the series of the last scrape."""

from __future__ import annotations

import threading
import urllib.request


class Scraper:
    """Fetches `url` every `interval_s` on a thread until `stop`."""

    def __init__(self, url: str, interval_s: float) -> None:
        self.url = url
        self.interval_s = interval_s
        self.scrapes = 0
        self.failures = 0
        self.series = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.wait(self.interval_s):
            try:
                with urllib.request.urlopen(self.url, timeout=10) as response:
                    text = response.read().decode()
            except OSError:
                self.failures += 1
                continue
            self.scrapes += 1
            self.series = sum(1 for line in text.splitlines() if line and not line.startswith("#"))

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(timeout=15)
