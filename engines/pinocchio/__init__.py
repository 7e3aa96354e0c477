"""The Pinocchio engine adapter (`adapter`); the engine library is imported
by the adapter module, never here, so that the registry imports nothing
for other engines."""
