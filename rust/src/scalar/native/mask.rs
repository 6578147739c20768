//! [`LaneMask`]'s traits: the comparisons' per-lane conditions as simba's `SimdBool`, in
//! the ISA's mask form.

use super::*;

impl<I: Isa<L>, const L: usize> fmt::Debug for LaneMask<I, L> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "LaneMask({:0w$b})", I::mask_bits(self.0), w = L)
    }
}

impl<I: Isa<L>, const L: usize> PartialEq for LaneMask<I, L> {
    #[inline(always)]
    fn eq(&self, other: &Self) -> bool {
        I::mask_bits(self.0) == I::mask_bits(other.0)
    }
}

impl<I: Isa<L>, const L: usize> Not for LaneMask<I, L> {
    type Output = Self;
    #[inline(always)]
    fn not(self) -> Self {
        Self(I::mask_not(self.0))
    }
}

impl<I: Isa<L>, const L: usize> BitAnd for LaneMask<I, L> {
    type Output = Self;
    #[inline(always)]
    fn bitand(self, rhs: Self) -> Self {
        Self(I::mask_and(self.0, rhs.0))
    }
}

impl<I: Isa<L>, const L: usize> BitOr for LaneMask<I, L> {
    type Output = Self;
    #[inline(always)]
    fn bitor(self, rhs: Self) -> Self {
        Self(I::mask_or(self.0, rhs.0))
    }
}

impl<I: Isa<L>, const L: usize> BitXor for LaneMask<I, L> {
    type Output = Self;
    #[inline(always)]
    fn bitxor(self, rhs: Self) -> Self {
        Self(I::mask_xor(self.0, rhs.0))
    }
}

impl<I: Isa<L>, const L: usize> SimdValue for LaneMask<I, L> {
    const LANES: usize = L;
    type Element = bool;
    type SimdBool = Self;

    #[inline(always)]
    fn splat(val: bool) -> Self {
        Self(I::mask_from_bits(if val { full(L) } else { 0 }))
    }

    #[inline(always)]
    fn extract(&self, i: usize) -> bool {
        assert!(i < L, "lane {i} of {L}");
        (I::mask_bits(self.0) >> i) & 1 == 1
    }

    #[inline(always)]
    unsafe fn extract_unchecked(&self, i: usize) -> bool {
        (I::mask_bits(self.0) >> i) & 1 == 1
    }

    #[inline(always)]
    fn replace(&mut self, i: usize, val: bool) {
        assert!(i < L, "lane {i} of {L}");
        // SAFETY: i < L, checked above.
        unsafe { self.replace_unchecked(i, val) }
    }

    #[inline(always)]
    unsafe fn replace_unchecked(&mut self, i: usize, val: bool) {
        let bits = (I::mask_bits(self.0) & !(1 << i)) | (u8::from(val) << i);
        self.0 = I::mask_from_bits(bits);
    }

    #[inline(always)]
    fn select(self, cond: Self, other: Self) -> Self {
        (self & cond) | (other & !cond)
    }
}

impl<I: Isa<L>, const L: usize> SimdBool for LaneMask<I, L> {
    #[inline(always)]
    fn bitmask(self) -> u64 {
        u64::from(I::mask_bits(self.0))
    }

    #[inline(always)]
    fn and(self) -> bool {
        I::mask_bits(self.0) == full(L)
    }

    #[inline(always)]
    fn or(self) -> bool {
        I::mask_bits(self.0) != 0
    }

    #[inline(always)]
    fn xor(self) -> bool {
        I::mask_bits(self.0).count_ones() % 2 == 1
    }

    #[inline(always)]
    fn all(self) -> bool {
        self.and()
    }

    #[inline(always)]
    fn any(self) -> bool {
        self.or()
    }

    #[inline(always)]
    fn none(self) -> bool {
        I::mask_bits(self.0) == 0
    }

    #[inline(always)]
    fn if_else<Res: SimdValue<SimdBool = Self>>(
        self,
        if_value: impl FnOnce() -> Res,
        else_value: impl FnOnce() -> Res,
    ) -> Res {
        let a = if_value();
        a.select(self, else_value())
    }

    #[inline(always)]
    fn if_else2<Res: SimdValue<SimdBool = Self>>(
        self,
        if_value: impl FnOnce() -> Res,
        else_if: (impl FnOnce() -> Self, impl FnOnce() -> Res),
        else_value: impl FnOnce() -> Res,
    ) -> Res {
        let a = if_value();
        let b = else_if.1();
        let c = else_value();
        a.select(self, b.select(else_if.0(), c))
    }

    #[inline(always)]
    fn if_else3<Res: SimdValue<SimdBool = Self>>(
        self,
        if_value: impl FnOnce() -> Res,
        else_if: (impl FnOnce() -> Self, impl FnOnce() -> Res),
        else_else_if: (impl FnOnce() -> Self, impl FnOnce() -> Res),
        else_value: impl FnOnce() -> Res,
    ) -> Res {
        let a = if_value();
        let b = else_if.1();
        let c = else_else_if.1();
        let d = else_value();
        let inner = c.select(else_else_if.0(), d);
        a.select(self, b.select(else_if.0(), inner))
    }
}
