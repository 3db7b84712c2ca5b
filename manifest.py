# Freeze tempcomp into a MicroPython firmware build:
#   include("path/to/tempcomp/manifest.py") in your board manifest.
metadata(description="Temperature compensation for MEMS gyros and accelerometers", version="0.1.0")
package("tempcomp", base_path="lib", opt=3)
