"""Verification: checks of lopcook outputs against independent references (e.g. the Khronos glTF validator)."""
