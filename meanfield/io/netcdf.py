"""A NetCDF dataset as plain data: written with h5netcdf directly, or turned into an xarray Dataset on request.

A run's ``timeseries.nc`` is described once, as a :class:`NetCDFDataset`: its variables by name, each
a :class:`NetCDFVariable` (dimensions, a numpy array, attributes), its coordinates (the variables named
after their dimension) and its global attributes.  From that one description

* :meth:`NetCDFDataset.write_netcdf` writes the file with :class:`h5netcdf.File`, without importing
  xarray or pandas (issue 45: with the dataset's building, up to 1.9 s, more than a small crowd's run);
* :meth:`NetCDFDataset.to_xarray` builds the :class:`xarray.Dataset` for whoever asks for one.

The written file is the one ``to_xarray().to_netcdf(path, engine="h5netcdf")`` writes: the same calls
on h5netcdf in the same order (global attributes, dimensions, then the data variables and the
coordinates, each with its attributes), and the same encoding, which is xarray's default with one
rule of the toolkit's:

* a coordinate has no ``_FillValue`` (CF 2.5.1: a coordinate has no missing values);
* a floating-point data variable has ``_FillValue = NaN`` (xarray's default for floats);
* an integer variable has none.

So ``xr.open_dataset(path, engine="h5netcdf")`` reads the same dataset either way
(``tests/io/test_netcdf.py`` holds them identical, raw HDF5 attributes included).

For the toolkit's own readers (the summary, the figures, the trajectory writers) a
:class:`NetCDFDataset` answers the few questions they ask of an :class:`xarray.Dataset` the same
way: ``ds[name].values``, ``.dims``, ``.dtype`` and ``.attrs``, ``name in ds``, ``ds.sizes``,
``ds.attrs``, ``ds.data_vars`` and ``ds.coords``.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["NetCDFVariable", "NetCDFDataset"]


@dataclass(eq=False)
class NetCDFVariable:
    """One variable of a :class:`NetCDFDataset`.

    Attributes
    ----------
    dims : tuple of str
        Its dimensions, one per axis of ``values``.
    values : ndarray
        Its data: numbers (integers or floats).
    attrs : dict
        Its attributes (strings, numbers, numpy arrays of numbers), in the order they are written.
    """

    dims: tuple[str, ...]
    values: np.ndarray
    attrs: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.dims = tuple(self.dims)
        self.values = np.asarray(self.values)
        if self.values.ndim != len(self.dims):
            raise ValueError(f"dims {self.dims} for an array of shape {self.values.shape}")
        if self.values.dtype.kind not in "iuf":
            raise TypeError(f"a NetCDFVariable holds integers or floats, not {self.values.dtype}")

    @property
    def dtype(self) -> np.dtype:
        """The dtype of ``values``."""
        return self.values.dtype

    @property
    def shape(self) -> tuple[int, ...]:
        """The shape of ``values``."""
        return self.values.shape

    def __repr__(self) -> str:
        return f"NetCDFVariable(dims={self.dims}, {self.dtype}{list(self.shape)}, attrs={sorted(self.attrs)})"


@dataclass(eq=False)
class NetCDFDataset(Mapping[str, NetCDFVariable]):
    """A NetCDF dataset as plain data (see the module's description).

    As a mapping it holds every variable, the data variables first, then the coordinates, the order in
    which they are written.

    Attributes
    ----------
    data_vars : dict of str to NetCDFVariable
        The data variables, in order.
    coords : dict of str to NetCDFVariable
        The coordinates: each is one-dimensional, named after its dimension.
    attrs : dict
        The global attributes, in order.
    """

    data_vars: dict[str, NetCDFVariable]
    coords: dict[str, NetCDFVariable]
    attrs: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        for name, var in self.coords.items():
            if var.dims != (name,):
                raise ValueError(f"coordinate {name!r} has dims {var.dims}: a coordinate is named after its one dim")
        both = set(self.data_vars) & set(self.coords)
        if both:
            raise ValueError(f"names both a data variable and a coordinate: {sorted(both)}")
        _ = self.sizes  # (raises unless every dimension has one length throughout)

    @property
    def variables(self) -> dict[str, NetCDFVariable]:
        """Every variable by name, the data variables first (the variables themselves, not copies)."""
        return {**self.data_vars, **self.coords}

    def __getitem__(self, name: str) -> NetCDFVariable:
        if name in self.data_vars:
            return self.data_vars[name]
        return self.coords[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self.variables)

    def __len__(self) -> int:
        return len(self.data_vars) + len(self.coords)

    def __repr__(self) -> str:
        sizes = ", ".join(f"{k}: {v}" for k, v in self.sizes.items())
        return f"NetCDFDataset(({sizes}), data_vars={list(self.data_vars)}, coords={list(self.coords)})"

    @property
    def sizes(self) -> dict[str, int]:
        """Each dimension's length, in the order the dimensions first appear (data variables first).

        Raises
        ------
        ValueError
            If two variables give one dimension two lengths.
        """
        out: dict[str, int] = {}
        for name, var in self.variables.items():
            for dim, n in zip(var.dims, var.shape, strict=True):
                if out.setdefault(dim, n) != n:
                    raise ValueError(f"dimension {dim!r} of length {out[dim]} and {n} (variable {name!r})")
        return out

    def write_netcdf(self, path: str | Path) -> None:
        """Write the dataset as a NetCDF-4 file with h5netcdf (no xarray): the file ``to_xarray().to_netcdf``
        writes with ``engine="h5netcdf"``.

        Parameters
        ----------
        path : str or Path
            The file, created or overwritten (:func:`meanfield.io.atomic.atomic_write_with` writes it
            atomically).
        """
        import h5netcdf

        with h5netcdf.File(path, "w") as f:
            for key, value in self.attrs.items():
                f.attrs[key] = value
            for dim, n in self.sizes.items():
                f.dimensions[dim] = n
            for name, var in self.variables.items():
                out = f.create_variable(name, dimensions=var.dims, dtype=var.dtype, fillvalue=self._fill_value(name))
                for key, value in var.attrs.items():
                    out.attrs[key] = value
                out[...] = var.values

    def _fill_value(self, name: str) -> Any:
        """The ``_FillValue`` of a variable: none for a coordinate or integers, NaN for floating-point data."""
        var = self[name]
        if name in self.coords or var.dtype.kind != "f":
            return None
        return var.dtype.type(np.nan)

    def to_xarray(self) -> Any:
        """The dataset as an :class:`xarray.Dataset` (imports xarray).

        Its arrays are this dataset's own (not copied); its attributes are copies.  Its coordinates
        carry the encoding ``_FillValue = None``, so that its ``to_netcdf`` writes the file
        :meth:`write_netcdf` writes.
        """
        import xarray as xr

        def tuple_of(var: NetCDFVariable) -> tuple:
            return var.dims, var.values, dict(var.attrs)

        ds = xr.Dataset(
            data_vars={name: tuple_of(var) for name, var in self.data_vars.items()},
            coords={name: tuple_of(var) for name, var in self.coords.items()},
            attrs=dict(self.attrs),
        )
        for name in self.coords:
            ds.variables[name].encoding["_FillValue"] = None
        return ds
