"""lampfab: design a caustic projection lamp from an image and export files to make it.

Units: millimetres throughout; the lamp frame is the STL frame (Z up, base on z = 0,
lamp axis on the z axis).  Heavy libraries (Mitsuba, Dr.Jit, OCP) are imported only
inside the functions that need them, so ``lampfab --help`` stays instant.
"""

__version__ = "0.1.0"
