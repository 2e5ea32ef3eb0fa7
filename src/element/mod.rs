//! The co-rotational 3D beam element (paper section 2).
