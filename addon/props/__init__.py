"""PropertyGroups attached as ``<ID>.lamina`` (Material, Light, Scene). Data only; no drawing."""
