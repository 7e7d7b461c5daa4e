"""Plugin protocol (DESIGN section 4): the manifest schema, atomic export by components, and
discovery and isolated loading by executors.

Skillsets and drivers call `exporting.export_plugin`; the executor calls `discovery.discover` and
`loading.load_plugins`. The manifest and its `<TreeNodesModel>` rendering need no ROS.
"""
