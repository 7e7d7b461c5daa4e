"""BT.CPP 4 scripting language: tokenizer, Pratt parser compiled to closures; never uses eval."""

from coral_core.bt.scripting.parser import ScriptEnv, compile_condition, compile_script

__all__ = ["ScriptEnv", "compile_condition", "compile_script"]
