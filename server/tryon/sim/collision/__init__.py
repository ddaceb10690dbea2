"""Collision: garment points against the body (and, for outfits, against the garments under them).

- ``kernels``: the body collision itself (paper 3.3-3.4): the offset body, each part's oriented box and
  cylinder map, the inside test along a ray from the part's axis and the push out (eq. 4), the penetration
  depth the metrics report. The maps are built with the body (``tryon.body.maps``); these kernels read them.
- ``collider``: ``BodyCollider``, the body as one drape sees it (mutable copies of what the kernels read:
  the offset surface, growth toward each part's axis, the arms turned rigidly), and which parts a garment
  can reach at all (``relevant_parts``).
- ``contacts``: the planes a collision leaves, projection onto them with Coulomb friction, reusing them
  while a contact rests, which points to test again, pinches.
- ``inside``: is a point of a triangle's plane inside the triangle (three tests, SPEC section 4).
- ``crossings``: where cloth went through cloth, measured; ``untangle``: a garment's own crossings taken back
  out (intersection-contour minimisation).
"""
