"""The Coral executor: runs one behavior tree with behaviors loaded at runtime from plugins.

Entry points: `python -m coral.executor` / `coral executor` (`cli`), `running.run_executor`.
"""
