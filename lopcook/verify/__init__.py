"""Verification: checks of lopcook outputs against independent references.

* ``gltf_validator``: glTF files written by ``lopcook decode`` against the Khronos glTF validator.
* ``gpu`` + ``decoders`` (``lopcook verify OUT.lop --decoders``): the GLSL/HLSL decoders and adaption
  kernels of ``shaders/`` against the CPU reference, bit for bit (headless moderngl through EGL).
* ``render`` + ``metrics`` (``lopcook verify OUT.lop --source SOURCE``): the float source, AP and CAP
  rendered from 20 icosahedron views at the distance where the half-pixel criterion selects each
  per-buffer level (positions decoded by the shipped GLSL decoder in the vertex shader); PSNR over
  object pixels, max error, share of pixels off by more than 1/255, depth-order errors from a
  part-ID target; ``render.evaluate`` returns it all as plain data (+ numpy images on request).
* ``calibrate`` (``lopcook calibrate``, ``lopcook cook --target-psnr``): the k_f scale with the least
  memory whose CAP renders reach a target PSNR, and the memory-vs-PSNR curve over k_f.
"""
