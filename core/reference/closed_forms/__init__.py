"""Closed-form kinematics of the four classic linkages (fourbar,
slider_crank, inverted_slider, slotted_lever) and their shared loop-closure
pieces (loop)."""
