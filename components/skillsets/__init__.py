"""Reference Coral skillsets (each folder holds one skillset and its Dockerfile)."""
