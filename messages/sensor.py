"""Sensor messages with ROS 2 ``sensor_msgs`` fields: Image, CameraInfo, RegionOfInterest, PointField,
PointCloud2, plus numpy helpers (``Image.from_array``/``to_array``, ``PointCloud2.from_structured``/
``to_structured``/``from_array``/``to_array``).

Bulk data (``Image.data``, ``PointCloud2.data``) is a 1-D ``uint8`` ndarray of raw bytes, as in ROS 2;
the helpers give typed, shaped views of those bytes without copying where the layout allows.
"""

from __future__ import annotations

import numpy as np

from .image_encodings import default_encoding, pixel_layout
from .point_cloud_layout import datatype_of as _datatype_of
from .point_cloud_layout import field_layouts, point_field_names, structured_dtype
from .schema import Message, array, message, nested, nested_list, scalar, sequence
from .std import Header

__all__ = ["Image", "RegionOfInterest", "CameraInfo", "PointField", "PointCloud2"]

# Number of distortion coefficients a distortion model needs (ROS 2 camera_calibration_parsers).
_DISTORTION_LENGTHS = {"plumb_bob": 5, "rational_polynomial": 8, "equidistant": 4}


def _is_big_endian(dtype: np.dtype) -> bool:
    return dtype.byteorder == ">" or (dtype.byteorder == "=" and not np.little_endian)


def _bytes_of(array: np.ndarray) -> np.ndarray:
    """The bytes of a C-contiguous array as a 1-D uint8 view (no copy)."""
    return array.reshape(-1).view(np.uint8)


@message("sensor_msgs/msg/Image", version=1)
class Image(Message):
    """An uncompressed image, ROS 2 ``sensor_msgs/msg/Image``.

    Attributes
    ----------
    header : Header
        ``stamp``: exposure start; ``frame_id``: the camera's optical frame (x right, y down, z forward).
    height, width : int
        Rows and columns, pixels (uint32).
    encoding : str
        Pixel layout, e.g. ``"mono8"``, ``"mono16"``, ``"32FC1"``, ``"rgb8"``, ``"bgr8"``
        (:mod:`dptpu.messages.image_encodings`).
    is_bigendian : int
        1 if multi-byte pixel values are big-endian, else 0 (uint8).
    step : int
        Bytes per row, ``>= width * channels * bytes_per_channel`` (uint32).
    data : ndarray (step * height,) uint8
        Raw row-major pixel bytes.

    Convention: pixel ``(row, col)`` of channel ``c`` starts at byte ``row*step + (col*channels + c)*itemsize``;
    the centre of the top-left pixel is (0, 0).
    """

    header: Header = nested(Header)
    height: int = scalar("uint32")
    width: int = scalar("uint32")
    encoding: str = scalar("string")
    is_bigendian: int = scalar("uint8")
    step: int = scalar("uint32")
    data: np.ndarray = array("uint8", ("step * height",))

    @classmethod
    def from_array(cls, array: np.ndarray, encoding: str | None = None, *, header: Header | None = None) -> Image:
        """An Image whose ``data`` is the bytes of ``array`` (a view when ``array`` is C-contiguous).

        Parameters
        ----------
        array : ndarray (H, W) or (H, W, C)
            Pixels; a non-C-contiguous array is copied once into a contiguous one.
        encoding : str, optional
            Must match the array's dtype and channel count; by default ``mono8``/``mono16``/``32FC1``/
            ``64FC1`` for (H, W) uint8/uint16/float32/float64, ``rgb8``/``rgba8``/``rgb16``/``rgba16`` for
            3/4-channel uint8/uint16, else the generic ``{bits}{U,S,F}C{C}``.
        header : Header, optional
            Stamp and frame (default: an empty Header).

        Returns
        -------
        Image
            ``step = W * C * itemsize``; ``is_bigendian`` from the array's byte order.
        """
        if not isinstance(array, np.ndarray) or array.ndim not in (2, 3):
            shape = getattr(array, "shape", None)
            raise ValueError(f"image array must be an ndarray of shape (H, W) or (H, W, C); got {shape!r}")
        channels = 1 if array.ndim == 2 else array.shape[2]
        if encoding is None:
            encoding = default_encoding(array.dtype, channels)
        layout = pixel_layout(encoding)
        if array.dtype.newbyteorder("=") != layout.dtype or channels != layout.channels:
            raise ValueError(f"encoding {encoding!r} needs {layout.channels} channel(s) of {layout.dtype}; got "
                             f"array of shape {array.shape} and dtype {array.dtype}")
        array = np.ascontiguousarray(array)
        height, width = array.shape[:2]
        return cls(header=Header() if header is None else header, height=height, width=width, encoding=encoding,
                   is_bigendian=int(array.dtype.itemsize > 1 and _is_big_endian(array.dtype)),
                   step=width * channels * array.dtype.itemsize, data=_bytes_of(array))

    def to_array(self) -> np.ndarray:
        """The pixels as an (H, W) array (one channel) or (H, W, C) array, a view of ``data``.

        Returns
        -------
        ndarray (H, W) or (H, W, C)
            The encoding's dtype in the byte order of ``is_bigendian``; read-only when ``data`` is
            (as after decoding); rows padded to ``step`` bytes are skipped by strides, never copied.

        Raises
        ------
        ValueError
            Unknown encoding, ``data`` not 1-D uint8, ``step`` shorter than a row of pixels, or
            ``len(data) != step * height``.
        """
        layout = pixel_layout(self.encoding)
        data = self.data
        if not isinstance(data, np.ndarray) or data.dtype != np.uint8 or data.ndim != 1:
            raise ValueError(f"Image.data must be a 1-D uint8 ndarray; got {_describe(data)}")
        dtype = layout.dtype.newbyteorder(">" if self.is_bigendian else "<")
        row_bytes = self.width * layout.channels * dtype.itemsize
        if self.step < row_bytes:
            raise ValueError(f"Image.step must be >= width * channels * itemsize = {self.width} * "
                             f"{layout.channels} * {dtype.itemsize} = {row_bytes} for {self.encoding!r}; "
                             f"got {self.step}")
        if data.size != self.step * self.height:
            raise ValueError(f"Image.data must hold step * height = {self.step} * {self.height} = "
                             f"{self.step * self.height} bytes; got {data.size}")
        rows = data.reshape(self.height, self.step)[:, :row_bytes]  # (H, row_bytes), rows may be strided
        pixels = rows.view(dtype).reshape(self.height, self.width, layout.channels)
        return pixels[:, :, 0] if layout.channels == 1 else pixels

    def check_consistency(self) -> None:
        if self.is_bigendian not in (0, 1):
            raise ValueError(f"Image.is_bigendian must be 0 or 1; got {self.is_bigendian}")
        if self.data.size != self.step * self.height:
            raise ValueError(f"Image.data must hold step * height = {self.step} * {self.height} = "
                             f"{self.step * self.height} bytes; got {self.data.size}")
        try:
            layout = pixel_layout(self.encoding)
        except ValueError:
            return  # other ROS encodings (yuv422, ...) travel unchecked; to_array refuses them
        row_bytes = self.width * layout.channels * layout.dtype.itemsize
        if self.step < row_bytes:
            raise ValueError(f"Image.step must be >= {row_bytes} bytes for {self.width} pixels of "
                             f"{self.encoding!r}; got {self.step}")


@message("sensor_msgs/msg/RegionOfInterest", version=1)
class RegionOfInterest(Message):
    """A sub-window of a camera image, ROS 2 ``sensor_msgs/msg/RegionOfInterest`` (pixels, uint32).

    Attributes
    ----------
    x_offset, y_offset : int
        Left column and top row of the window (0 = the full image's first pixel).
    height, width : int
        Window size; 0 means the full resolution.
    do_rectify : bool
        True if a rectified sub-window is wanted.
    """

    x_offset: int = scalar("uint32")
    y_offset: int = scalar("uint32")
    height: int = scalar("uint32")
    width: int = scalar("uint32")
    do_rectify: bool = scalar("bool")


@message("sensor_msgs/msg/CameraInfo", version=1)
class CameraInfo(Message):
    """Pinhole camera calibration, ROS 2 ``sensor_msgs/msg/CameraInfo``.

    Attributes
    ----------
    header : Header
        Stamp and the camera's optical frame.
    height, width : int
        Calibrated image size, pixels.
    distortion_model : str
        ``"plumb_bob"`` (``d = k1, k2, p1, p2, k3``, OpenCV order), ``"rational_polynomial"`` (8) or
        ``"equidistant"`` (4).
    d : ndarray (n,) float64
        Distortion coefficients, unitless.
    k : ndarray (9,) float64
        Intrinsic matrix ``[fx 0 cx; 0 fy cy; 0 0 1]`` row-major, pixels.
    r : ndarray (9,) float64
        Rectification rotation, row-major (identity for a monocular camera).
    p : ndarray (12,) float64
        Projection matrix ``[fx' 0 cx' Tx; 0 fy' cy' Ty; 0 0 1 0]`` row-major, pixels (``Tx`` in
        pixel-metres for a stereo right camera).
    binning_x, binning_y : int
        Binning factors (0 or 1 = none).
    roi : RegionOfInterest
        Sub-window the image was captured with.

    Convention: pixel centres are integer coordinates, top-left pixel (0, 0) (OpenCV and Bouguet).
    """

    header: Header = nested(Header)
    height: int = scalar("uint32")
    width: int = scalar("uint32")
    distortion_model: str = scalar("string")
    d: np.ndarray = sequence("float64")
    k: np.ndarray = sequence("float64", 9)
    r: np.ndarray = sequence("float64", 9)
    p: np.ndarray = sequence("float64", 12)
    binning_x: int = scalar("uint32")
    binning_y: int = scalar("uint32")
    roi: RegionOfInterest = nested(RegionOfInterest)

    @classmethod
    def from_intrinsics(cls, camera_matrix, distortion, width: int, height: int, *,
                        header: Header | None = None) -> CameraInfo:
        """CameraInfo of a monocular ``plumb_bob`` camera: ``r`` = identity, ``p = [K | 0]``.

        Parameters
        ----------
        camera_matrix : array_like (3, 3)
            Intrinsic matrix K, pixels.
        distortion : array_like (5,)
            ``k1, k2, p1, p2, k3`` (OpenCV order).
        width, height : int
            Image size, pixels.
        header : Header, optional
        """
        k = np.asarray(camera_matrix, dtype=np.float64)
        d = np.asarray(distortion, dtype=np.float64)
        if k.shape != (3, 3):
            raise ValueError(f"camera_matrix must have shape (3, 3); got {k.shape}")
        if d.shape != (5,):
            raise ValueError(f"distortion must have shape (5,) (k1, k2, p1, p2, k3); got {d.shape}")
        p = np.hstack([k, np.zeros((3, 1))])  # (3, 4)
        return cls(header=Header() if header is None else header, height=height, width=width,
                   distortion_model="plumb_bob", d=d.copy(), k=k.reshape(9).copy(), r=np.eye(3).reshape(9),
                   p=p.reshape(12))

    def check_consistency(self) -> None:
        expected = _DISTORTION_LENGTHS.get(self.distortion_model)
        if expected is not None and len(self.d) != expected:
            raise ValueError(f"CameraInfo.d must have {expected} coefficients for distortion_model "
                             f"{self.distortion_model!r}; got {len(self.d)}")


@message("sensor_msgs/msg/PointField", version=1)
class PointField(Message):
    """One field of a PointCloud2 point, ROS 2 ``sensor_msgs/msg/PointField``.

    Attributes
    ----------
    name : str
        Field name, e.g. ``"x"`` (metres), ``"intensity"``.
    offset : int
        Byte offset of the field from the start of the point (uint32).
    datatype : int
        Element type: one of the constants ``INT8 = 1`` ... ``FLOAT64 = 8`` (uint8).
    count : int
        Number of elements in the field (uint32, usually 1).
    """

    INT8 = 1
    UINT8 = 2
    INT16 = 3
    UINT16 = 4
    INT32 = 5
    UINT32 = 6
    FLOAT32 = 7
    FLOAT64 = 8

    name: str = scalar("string")
    offset: int = scalar("uint32")
    datatype: int = scalar("uint8")
    count: int = scalar("uint32", default=1)


@message("sensor_msgs/msg/PointCloud2", version=1)
class PointCloud2(Message):
    """A point cloud, ROS 2 ``sensor_msgs/msg/PointCloud2``.

    Attributes
    ----------
    header : Header
        Stamp and frame of the points (``scanner_optical_frame``: x right, y down, z forward, metres).
    height, width : int
        Organized cloud: image rows and columns; unorganized: ``height = 1``, ``width`` = points.
    fields : list of PointField
        Layout of one point.
    is_bigendian : bool
        Byte order of multi-byte fields.
    point_step : int
        Bytes per point.
    row_step : int
        Bytes per row, ``>= width * point_step``.
    data : ndarray (row_step * height,) uint8
        Raw point bytes, row-major.
    is_dense : bool
        True if no point is invalid (no NaN); an organized cloud with NaN holes has ``is_dense = False``.
    """

    header: Header = nested(Header)
    height: int = scalar("uint32")
    width: int = scalar("uint32")
    fields: list = nested_list(PointField)
    is_bigendian: bool = scalar("bool")
    point_step: int = scalar("uint32")
    row_step: int = scalar("uint32")
    data: np.ndarray = array("uint8", ("row_step * height",))
    is_dense: bool = scalar("bool")

    @classmethod
    def from_structured(cls, points: np.ndarray, *, header: Header | None = None,
                        is_dense: bool | None = None) -> PointCloud2:
        """A cloud whose points are the records of a structured array (a view when C-contiguous).

        Parameters
        ----------
        points : ndarray (H, W) or (N,) structured
            Fields of int8 ... float64 (a 1-D sub-array field becomes ``count > 1``), all in one byte
            order. (N,) gives an unorganized cloud with ``height = 1``.
        header : Header, optional
        is_dense : bool, optional
            Default: True iff no floating-point field holds a NaN.

        Returns
        -------
        PointCloud2
            ``point_step = points.dtype.itemsize``, ``row_step = W * point_step``, field offsets as in
            the dtype.
        """
        if not isinstance(points, np.ndarray) or points.ndim not in (1, 2):
            raise ValueError(f"points must be a structured ndarray of shape (H, W) or (N,); got "
                             f"{_describe(points)}")
        layouts, big_endian = field_layouts(points.dtype)
        grid = points.reshape(1, -1) if points.ndim == 1 else points  # (H, W)
        grid = np.ascontiguousarray(grid)
        if is_dense is None:
            is_dense = not any(np.isnan(grid[layout.name]).any() for layout in layouts
                               if grid.dtype[layout.name].base.kind == "f")
        height, width = grid.shape
        point_step = points.dtype.itemsize
        return cls(header=Header() if header is None else header, height=height, width=width,
                   fields=[PointField(name=f.name, offset=f.offset, datatype=f.datatype, count=f.count)
                           for f in layouts],
                   is_bigendian=big_endian, point_step=point_step, row_step=width * point_step,
                   data=_bytes_of(grid), is_dense=bool(is_dense))

    def point_dtype(self) -> np.dtype:
        """The structured dtype of one point (itemsize ``point_step``) described by ``fields``."""
        return structured_dtype(self.fields, self.point_step, self.is_bigendian)

    def to_structured(self) -> np.ndarray:
        """The points as an (H, W) structured array: a view of ``data`` (read-only when ``data`` is).

        Raises
        ------
        ValueError
            Inconsistent ``fields``/``point_step``/``row_step``/``data`` (the message says which).
        """
        self._check_layout()
        dtype = self.point_dtype()
        if self.point_step == 0:  # no fields: points of zero bytes
            return np.empty((self.height, self.width), dtype)
        rows = self.data.reshape(self.height, self.row_step)[:, :self.width * self.point_step]  # (H, W*step)
        return rows.view(dtype)  # (H, W)

    @classmethod
    def from_array(cls, array: np.ndarray, field_names, *, header: Header | None = None,
                   is_dense: bool | None = None) -> PointCloud2:
        """A cloud of ``C`` float fields from an (H, W, C) or (N, C) array (a view when C-contiguous).

        Parameters
        ----------
        array : ndarray (H, W, C) or (N, C), float32 or float64
            Channel ``c`` becomes field ``field_names[c]`` at offset ``c * itemsize`` (FLOAT32 or
            FLOAT64). Organized clouds keep NaN where a pixel has no point. (N, C) gives ``height = 1``.
        field_names : sequence of str
            ``C`` distinct names, e.g. ``("x", "y", "z", "intensity")``; x, y, z in metres.
        header : Header, optional
        is_dense : bool, optional
            Default: True iff the array holds no NaN.

        Returns
        -------
        PointCloud2
            ``point_step = C * itemsize``, ``row_step = W * point_step``.
        """
        if not isinstance(array, np.ndarray) or array.ndim not in (2, 3):
            raise ValueError(f"array must have shape (H, W, C) or (N, C); got {_describe(array)}")
        if array.dtype.kind != "f" or array.dtype.itemsize not in (4, 8):
            raise ValueError(f"array must be float32 or float64; got {array.dtype}")
        names = _field_name_list(field_names)
        if len(names) != array.shape[-1]:
            raise ValueError(f"field_names must name all {array.shape[-1]} channels of an array of shape "
                             f"{array.shape}; got {len(names)} names")
        grid = np.ascontiguousarray(array.reshape(1, *array.shape) if array.ndim == 2 else array)  # (H, W, C)
        height, width, channels = grid.shape
        itemsize = grid.dtype.itemsize
        datatype = _datatype_of(grid.dtype)
        if is_dense is None:
            is_dense = not np.isnan(grid).any()
        return cls(header=Header() if header is None else header, height=height, width=width,
                   fields=[PointField(name=name, offset=c * itemsize, datatype=datatype, count=1)
                           for c, name in enumerate(names)],
                   is_bigendian=bool(itemsize > 1 and _is_big_endian(grid.dtype)),
                   point_step=channels * itemsize, row_step=width * channels * itemsize, data=_bytes_of(grid),
                   is_dense=bool(is_dense))

    def to_array(self, field_names=None, *, dtype=None) -> np.ndarray:
        """The named fields as an (H, W, C) array.

        Parameters
        ----------
        field_names : sequence of str, optional
            Fields to read, in channel order (default: every field, in message order). Each must
            have ``count == 1``.
        dtype : numpy dtype, optional
            Output dtype (default: the common type of the fields, e.g. float32 for x, y, z float32).

        Returns
        -------
        ndarray (H, W, C)
            A view of ``data`` when the fields are consecutive from offset 0, of the output dtype,
            fill the whole point and no row padding exists (read-only when ``data`` is); a new array
            otherwise.
        """
        points = self.to_structured()  # (H, W)
        present = point_field_names(points.dtype)
        names = list(present) if field_names is None else _field_name_list(field_names)
        missing = [name for name in names if name not in present]
        if missing:
            raise ValueError(f"PointCloud2 has no field(s) {', '.join(map(repr, missing))}; it has "
                             f"{', '.join(map(repr, present))}")
        field_dtypes = [points.dtype[name] for name in names]
        for name, field_dtype in zip(names, field_dtypes):
            if field_dtype.subdtype is not None:
                raise ValueError(f"field {name!r} has count {field_dtype.shape[0]}; to_array reads count-1 "
                                 "fields only (use to_structured)")
        if dtype is None:
            dtype = np.result_type(*field_dtypes) if field_dtypes else np.dtype(np.float32)
        dtype = np.dtype(dtype)
        if self._is_plain_view_of(names, dtype):
            channels = self.data.view(dtype)  # (H * W * C,)
            return channels.reshape(self.height, self.width, len(names))
        out = np.empty((self.height, self.width, len(names)), dtype=dtype)
        for c, name in enumerate(names):
            out[:, :, c] = points[name]
        return out

    def _is_plain_view_of(self, names: list[str], dtype: np.dtype) -> bool:
        offsets = {field.name: field.offset for field in self.fields}
        point_dtype = self.point_dtype()
        return (all(point_dtype[name] == dtype for name in names)
                and all(offsets[name] == c * dtype.itemsize for c, name in enumerate(names))
                and self.point_step == len(names) * dtype.itemsize
                and self.row_step == self.width * self.point_step)

    def _check_layout(self) -> None:
        self.point_dtype()  # fields fit in point_step, known datatypes, unique names
        if self.row_step < self.width * self.point_step:
            raise ValueError(f"PointCloud2.row_step must be >= width * point_step = {self.width} * "
                             f"{self.point_step} = {self.width * self.point_step}; got {self.row_step}")
        data = self.data
        if not isinstance(data, np.ndarray) or data.dtype != np.uint8 or data.ndim != 1:
            raise ValueError(f"PointCloud2.data must be a 1-D uint8 ndarray; got {_describe(data)}")
        if data.size != self.row_step * self.height:
            raise ValueError(f"PointCloud2.data must hold row_step * height = {self.row_step} * {self.height} = "
                             f"{self.row_step * self.height} bytes; got {data.size}")

    def check_consistency(self) -> None:
        self._check_layout()


def _field_name_list(field_names) -> list[str]:
    if isinstance(field_names, str):
        raise ValueError(f"field_names must be a sequence of names such as ('x', 'y', 'z'); got the string "
                         f"{field_names!r}")
    names = list(field_names)
    if not all(isinstance(name, str) and name for name in names):
        raise ValueError(f"field_names must be non-empty strings; got {names!r}")
    if len(set(names)) != len(names):
        raise ValueError(f"field_names must be distinct; got {names!r}")
    return names


def _describe(value) -> str:
    if isinstance(value, np.ndarray):
        return f"ndarray of shape {value.shape} and dtype {value.dtype}"
    return type(value).__name__

