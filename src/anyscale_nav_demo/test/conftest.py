"""Makes the package's pure modules importable by pytest without a built workspace."""
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "src"))
