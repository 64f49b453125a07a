"""Boundary-value cases built on the femgran solver (CASES.md section 2)."""
