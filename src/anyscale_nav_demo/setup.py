# Installs the package's pure-Python modules (catkin_python_setup).
from setuptools import setup
from catkin_pkg.python_setup import generate_distutils_setup

setup(**generate_distutils_setup(packages=["anyscale_nav_demo"], package_dir={"": "src"}))
