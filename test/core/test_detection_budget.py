"""core.detect, the per-frame budgets of a busy frame: at most ``max_blur_fits`` chroma
fits and ``max_shifted`` blobs with moved refinement starts (the largest blobs first), and
a lean frame (``detect(..., lean=True)``) without any of these second attempts."""
from detection_helpers import _background, _diamond


def test_a_busy_frame_spends_a_bounded_number_of_chroma_fits(detector, monkeypatch):
    """``max_blur_fits``: a frame of many signs whose border line does not measure costs at
    most that many chroma fits, the largest blobs first; a frame under the budget is measured
    as without one."""
    from workzone_ros.core.detect import warning
    fitted = []
    real_fit = warning.fit_blurred_diamond

    def counting(chroma, start, *args, **kwargs):
        fitted.append(float(start[2]))
        return real_fit(chroma, start, *args, **kwargs)

    monkeypatch.setattr(warning, 'fit_blurred_diamond', counting)

    def no_line(max_fits):
        det = detector.with_config(max_blur_fits=max_fits)
        det._refine = lambda *args, **kwargs: None     # no face-to-line step anywhere
        return det

    img, x = _background(3), 40
    for r in (14, 30, 18, 26, 22, 16):
        _diamond(img, x + r, 120, r)
        x += 2 * r + 25
    unbounded, bounded = no_line(50), no_line(2)
    assert len(unbounded.detect(img)) == 6 and len(fitted) == 6
    assert not unbounded.budget_spent
    fitted.clear()
    assert len(bounded.detect(img)) >= 2
    assert len(fitted) == 2 and min(fitted) > 25.0          # the 30 and 26 px signs
    assert bounded.budget_spent == {'blur_fit'}
    one = _background(3)
    _diamond(one, 200, 120, 26)
    assert bounded.detect(one) == unbounded.detect(one) != []
    assert not bounded.budget_spent


def test_a_busy_frame_moves_the_starts_of_a_bounded_number_of_blobs(detector, monkeypatch):
    """``max_shifted``: on a frame of many large signs whose line measures from no start
    and whose chroma does not fit, the moved starts (eight refinements each) are tried on at
    most that many blobs, the largest first; a frame under the budget is measured as
    without one."""
    from workzone_ros.core.detect import warning
    moved = []
    real_shifted = warning.refine_shifted

    def counting(starts, *args, **kwargs):
        moved.append(float(starts[0][2]))
        return real_shifted(starts, *args, **kwargs)

    monkeypatch.setattr(warning, 'refine_shifted', counting)

    def no_line(max_shifted):
        det = detector.with_config(max_shifted=max_shifted, blur_fit=False)
        det._refine = lambda *args, **kwargs: None     # no face-to-line step anywhere
        return det

    img, x = _background(3), 30
    for r in (22, 34, 26, 30):
        _diamond(img, x + r, 150, r)
        x += 2 * r + 30
    unbounded, bounded = no_line(50), no_line(1)
    unbounded.detect(img)
    assert len(moved) == 4 and not unbounded.budget_spent
    moved.clear()
    bounded.detect(img)
    assert len(moved) == 1 and moved[0] > 28.0              # the 34 px sign's
    assert bounded.budget_spent == {'shifted'}
    one = _background(3)
    _diamond(one, 200, 150, 30)
    moved.clear()
    assert bounded.detect(one) == unbounded.detect(one) and len(moved) == 2
    assert not bounded.budget_spent


def test_a_lean_frame_skips_the_second_attempts_and_the_next_frame_does_not(detector,
                                                                           monkeypatch):
    """``detect(..., lean=True)`` (a caller behind its camera): no chroma fit, no grown
    blob and no moved refinement start on that frame, none of it counted as over a budget
    (six signs whose line does not measure are boxed from their masks); the next frame, not
    lean, is measured in full again."""
    from workzone_ros.core.detect import warning
    calls = []
    for name in ('fit_blurred_diamond', 'refine_shifted'):
        real = getattr(warning, name)
        monkeypatch.setattr(warning, name, lambda *a, _real=real, _name=name, **k: (
            calls.append(_name), _real(*a, **k))[1])
    det = detector.with_config(max_blur_fits=50)
    real_grown = det._grown
    det._grown = lambda *a, **k: (calls.append('grown'), real_grown(*a, **k))[1]
    det._refine = lambda *args, **kwargs: None          # no face-to-line step anywhere
    img, x = _background(3), 40
    for r in (14, 30, 18, 26, 22, 16):
        _diamond(img, x + r, 120, r)
        x += 2 * r + 25
    lean = det.detect(img, lean=True)                   # boxed from their masks' diamonds
    assert len(lean) == 6 and det.lean
    assert calls == [] and not det.budget_spent
    assert len(det.detect(img)) == 6 and not det.lean
    assert calls.count('fit_blurred_diamond') == 6
