"""The spatial reference: rigid bodies in three dimensions joined by
revolute, prismatic, cylindrical, spherical, universal, planar and fixed
joints, solved exactly (positions, rates, reactions) or integrated."""
