# Installs the anyscale_core Python package (catkin_python_setup reads this).
from setuptools import setup

from catkin_pkg.python_setup import generate_distutils_setup

setup(**generate_distutils_setup(packages=["anyscale_core", "anyscale_core.allocators"],
                                 package_dir={"": "src"}))
