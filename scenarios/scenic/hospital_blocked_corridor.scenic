"""A bed left across the east corridor beside spine block 3, with a cart pushed into the gap
next to it: the corridor is shut between cross corridors 2 and 3 (y -16 .. -23), so robots
must go round by the west corridor.

The corridor runs between x 3.6 and 6.4 there. The bed (2.1 m long, facing east) spans x
3.65 .. 5.75 and the cart (0.55 m wide) x 5.8 .. 6.35, leaving gaps of at most 0.1 m. Both
are allowed on the lanes (``regionContainedIn workspace``).
"""

model mrta_drake.world.scenic_model

y = Range(-19.0, -17.5)
new Bed at (4.7, y), facing -90 deg, with regionContainedIn workspace
new Cart at (6.07, y + Range(-0.2, 0.2)), with regionContainedIn workspace
