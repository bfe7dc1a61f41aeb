"""trackfw's built-in plugins.

Each sub-package is one plugin module, registered through the ``trackfw`` entry-point group of
this distribution exactly as a third-party plugin would be. Shared maths lives in
:mod:`trackfw_plugins.maths`.
"""
