"""The PyBullet engine: the adapter (`adapter.PybulletAdapter`), registered through
the `mechval.engines` entry point as a plug-in is. Nothing here imports
PyBullet at package import: the registry imports `adapter` when the engine is used.
"""
