"""`python -m coral.executor --tree FILE --plugins DIR [...]`, the same as `coral executor`."""

import logging
import os
import sys

from coral.executor.cli import executor_command

try:
    executor_command(prog_name="python -m coral.executor")
    code = 0
except SystemExit as done:
    code = done.code if isinstance(done.code, int) else (0 if done.code is None else 1)
# Everything is reported and ROS is shut down by now. Skipping the interpreter's teardown avoids
# an abort in native static destructors at exit (seen as exit code 134 after a SUCCESS), which
# would make Kubernetes run a finished mission again.
sys.stdout.flush()
sys.stderr.flush()
logging.shutdown()
os._exit(code)
