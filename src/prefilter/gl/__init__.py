"""OpenGL runtime: the context, the GLSL assembler, the renderer and the shader evaluator."""
