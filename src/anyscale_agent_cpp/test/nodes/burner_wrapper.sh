#!/bin/sh
# Test fixture: a wrapper that runs the burner as its child (no exec), like a launch script;
# the agent must measure the worker in the process group, not this idle shell.
"$(dirname "$0")/burner.py" "$@"
