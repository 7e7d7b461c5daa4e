"""The bottom layer that the robot side (`coral`) and the operator (`coral_operator`) both import.

It holds the contract between them and the libraries both need, and nothing else crosses between
the two (the import-linter contracts in `.importlinter` hold this):

- the contract: the coral.dev API's names (`names`), the CoralInstance status as it travels
  (`instance_status`, its wire names in `keys`, on the `wire.CamelModel` base), and the limits both
  sides check (`limits`);
- the libraries: the behavior-tree engine (`bt`: loader, validation, runtime) and the bounded
  parsers for text from outside the process (`parsing`);
- the `coral` command's group (`command`), whose verbs each installed side registers.

Both images install it; it imports neither side.
"""
