"""Verification: checks of lopcook outputs against independent references.

* ``gltf_validator``: glTF files written by ``lopcook decode`` against the Khronos glTF validator.
* ``gpu`` + ``decoders`` (``lopcook verify OUT.lop --decoders``): the GLSL/HLSL decoders and adaption
  kernels of ``shaders/`` against the CPU reference, bit for bit (headless moderngl through EGL);
  ``twins``: the GLSL and HLSL files of each pair change together.
* the render check (``lopcook verify OUT.lop --source SOURCE``): ``cameras`` (20 icosahedron views at
  the distance where the half-pixel criterion selects each per-buffer level), ``buffers`` (AP and
  CAP position buffers), ``glsl`` + ``renderer`` (positions decoded by the shipped GLSL decoder in
  the vertex shader), ``evaluate`` (float source vs AP vs CAP, returned as plain data, plus numpy
  images on request), ``metrics`` (PSNR over object pixels, max error, share of pixels off by more
  than 1/255, depth-order errors from a part-ID target), ``tables`` (the text table);
  ``baselines``: the uniform 16-bit and minimum-level scenes ``lopcook report`` renders beside them.

The k_f calibration and the byte-budget fit that use the render check live in ``lopcook.tune``.
"""
