"""Posing and solving identification problems: search spaces, a record and a structure
posed as one :class:`~flexid.optimisers.Problem`, the gradient references (least squares,
prediction error, subspace), the delay estimate, and the built-in model families that join
them.
"""

__all__: list[str] = []
