"""Local runtime: `coral run` and friends, running a Coral project as local processes."""
