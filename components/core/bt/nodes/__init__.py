"""Node classes: the base lifecycle (base.py) and BT.CPP's built-in controls, decorators and actions."""
