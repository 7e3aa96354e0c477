"""The MuJoCo engine: the adapter (`adapter.MujocoAdapter`), registered through
the `mechval.engines` entry point as a plug-in is. Nothing here imports
MuJoCo at package import: the registry imports `adapter` when the engine is used.
"""
