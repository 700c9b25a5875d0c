"""The model's parts: backlash.py (B, B_inv; eqs. 1-2), linear.py (G(s); eq. 3b), static.py (h; eq. 3c)."""
