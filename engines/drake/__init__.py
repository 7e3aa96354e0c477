"""The Drake engine: the adapter (`adapter.DrakeAdapter`), registered through
the `mechval.engines` entry point as a plug-in is. Nothing here imports
pydrake at package import: the registry imports `adapter` when the engine is used.
"""
