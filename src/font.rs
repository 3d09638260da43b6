//! A 3 × 5 pixel font for the labels on segloc's pictures (map pictures, stereo overlays).

/// Horizontal advance of one character, in font pixels (3 wide + 1 space).
pub const ADVANCE: i64 = 4;

/// Height of a character, in font pixels.
pub const HEIGHT: i64 = 5;

/// Calls `lit(x, y)` for every lit pixel of `text`, in font pixels from the top left of
/// the first character (characters advance by [`ADVANCE`]). Letters are drawn as capitals;
/// characters without a glyph are blank.
pub fn for_each_lit_pixel(text: &str, mut lit: impl FnMut(i64, i64)) {
    for (k, ch) in text.chars().enumerate() {
        for (row, bits) in rows(ch).iter().enumerate() {
            for col in 0..3 {
                if bits & (4 >> col) != 0 {
                    lit(k as i64 * ADVANCE + col, row as i64);
                }
            }
        }
    }
}

/// The rows of a character's glyph, top to bottom, 3 bits each (most significant = left).
fn rows(ch: char) -> [u8; 5] {
    match ch.to_ascii_uppercase() {
        '0' => [7, 5, 5, 5, 7],
        '1' => [2, 6, 2, 2, 7],
        '2' => [7, 1, 7, 4, 7],
        '3' => [7, 1, 7, 1, 7],
        '4' => [5, 5, 7, 1, 1],
        '5' => [7, 4, 7, 1, 7],
        '6' => [7, 4, 7, 5, 7],
        '7' => [7, 1, 1, 1, 1],
        '8' => [7, 5, 7, 5, 7],
        '9' => [7, 5, 7, 1, 7],
        'A' => [2, 5, 7, 5, 5],
        'B' => [6, 5, 6, 5, 6],
        'C' => [3, 4, 4, 4, 3],
        'D' => [6, 5, 5, 5, 6],
        'E' => [7, 4, 6, 4, 7],
        'F' => [7, 4, 6, 4, 4],
        'G' => [3, 4, 5, 5, 3],
        'H' => [5, 5, 7, 5, 5],
        'I' => [7, 2, 2, 2, 7],
        'J' => [1, 1, 1, 5, 2],
        'K' => [5, 5, 6, 5, 5],
        'L' => [4, 4, 4, 4, 7],
        'M' => [5, 7, 7, 5, 5],
        'N' => [6, 5, 5, 5, 5],
        'O' => [2, 5, 5, 5, 2],
        'P' => [6, 5, 6, 4, 4],
        'Q' => [2, 5, 5, 6, 3],
        'R' => [6, 5, 6, 5, 5],
        'S' => [3, 4, 2, 1, 6],
        'T' => [7, 2, 2, 2, 2],
        'U' => [5, 5, 5, 5, 7],
        'V' => [5, 5, 5, 5, 2],
        'W' => [5, 5, 7, 7, 5],
        'X' => [5, 5, 2, 5, 5],
        'Y' => [5, 5, 2, 2, 2],
        'Z' => [7, 1, 2, 4, 7],
        '.' => [0, 0, 0, 0, 2],
        ',' => [0, 0, 0, 2, 4],
        '-' => [0, 0, 7, 0, 0],
        '+' => [0, 2, 7, 2, 0],
        ':' => [0, 2, 0, 2, 0],
        '/' => [1, 1, 2, 4, 4],
        '(' => [2, 4, 4, 4, 2],
        ')' => [2, 1, 1, 1, 2],
        '%' => [5, 1, 2, 4, 5],
        '=' => [0, 7, 0, 7, 0],
        '<' => [1, 2, 4, 2, 1],
        '>' => [4, 2, 1, 2, 4],
        '_' => [0, 0, 0, 0, 7],
        _ => [0, 0, 0, 0, 0],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_is_a_narrow_column() {
        let mut lit = Vec::new();
        for_each_lit_pixel("1", |x, y| lit.push((x, y)));
        assert!(lit.contains(&(1, 0)) && lit.contains(&(0, 4)) && lit.contains(&(2, 4)));
        assert_eq!(lit.len(), 8);
        let mut count = 0;
        for_each_lit_pixel("?", |_, _| count += 1);
        assert_eq!(count, 0);
    }
}
