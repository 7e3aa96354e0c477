"""The Exudyn engine: the adapter (`adapter.ExudynAdapter`), registered through
the `mechval.engines` entry point as a plug-in is. Nothing here imports
Exudyn at package import: the registry imports `adapter` when the engine is used.
"""
