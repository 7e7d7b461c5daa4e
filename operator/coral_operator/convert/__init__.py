"""`coral convert`: Coral's three files (compose, tree XML, parameters YAML) to one CoralSystem."""
