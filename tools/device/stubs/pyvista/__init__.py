"""Device-only stand-in for pyvista (not installed on the borrowed machine; never on the path here).
Rendering raises, so dem.output.snapshot falls back to matplotlib; a grid keeps its cell data
and saves an empty file (excited.vtu is not brought back from the device)."""


class CellType:
    HEXAHEDRON = 12


class UnstructuredGrid:
    def __init__(self, *a, **k):
        self.cell_data, self.point_data, self.field_data = {}, {}, {}

    def save(self, path, *a, **k):
        open(path, "wb").close()


def __getattr__(name):
    raise AttributeError(f"pyvista stand-in: no {name} on this machine")
